"""Streets as the runtime sees them: the probes of a street, the runtime street (at most
``MAX_PROBES`` probes, what one draw uploads) and its GLSL uniforms.

The uniforms are one GLSL struct, ``EnvcapStreet`` (``shaders/runtime/envcap_street.glsl``),
declared as ``uniform EnvcapStreet envcap_street;`` by ``envcap_street_uniforms.glsl``;
:class:`StreetUniforms` mirrors it field for field (``tests/runtime/test_street_uniforms.py``
compiles the GLSL and checks names, types and lengths, and reads the values back).

Conventions: world meters, +Y up; a street runs along world axis ``along`` (0 = x, 2 = z);
``planes`` per probe are ``(facade_min, facade_max, ground)`` in absolute world coordinates (m).
The uniforms are street-local: world coordinates minus the street's ``origin`` (float64, kept on
:class:`StreetUniforms`, not uploaded), subtracted in float64 and rounded to float32 once, so that
a street 10^6 m from the world origin samples like the same street at the origin.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.probeset import manifest
from envcap.runtime.limits import MAX_LEVELS, MAX_PROBES
from envcap.runtime.mip import lobe_table
from envcap.runtime.parallax import check_along, nearest_probe
from envcap.scene.model import local_origin

PLANE_SETS = ("nominal", "fitted")
"""Plane sets of a probe: ``nominal`` (the street's planes, per probe) and ``fitted`` (fitted from
the probe's own depth where the bake could; nominal elsewhere)."""

GLSL_STRUCT = "EnvcapStreet"
"""Name of the GLSL struct that :class:`StreetUniforms` mirrors."""
GLSL_UNIFORM = "envcap_street"
"""Name of the uniform of type ``EnvcapStreet`` declared by ``envcap_street_uniforms.glsl``."""


@dataclass(frozen=True)
class RuntimeStreet:
    """One street of a probe set, as the runtime needs it (at most ``MAX_PROBES`` probes).

    ``along``: world axis index of the street (0 = x, 2 = z).  ``positions``: ``(P, 3)`` probe
    positions (m), sorted along the street; ``planes``: ``(P, 3)`` (facade_min, facade_max,
    ground) per probe (m); ``layers``: ``(P,)`` cube-array layer of each probe.
    """

    along: int
    positions: NDArray[np.float64]
    planes: NDArray[np.float64]
    layers: NDArray[np.int64]

    def __post_init__(self) -> None:
        check_along(self.along)
        P = self.positions.shape[0]
        if self.positions.shape != (P, 3) or self.planes.shape != (P, 3) or self.layers.shape != (P,):
            raise ValueError("RuntimeStreet: positions and planes must be (P, 3) and layers (P,)")
        if not 1 <= P <= MAX_PROBES:
            raise ValueError(f"RuntimeStreet: need 1..{MAX_PROBES} probes, got {P}")
        if not (np.all(np.isfinite(self.positions)) and np.all(np.isfinite(self.planes))):
            raise ValueError("RuntimeStreet: probe positions and planes must be finite")
        if np.any(np.diff(self.positions[:, self.along]) < 0):
            raise ValueError("RuntimeStreet: probes must be sorted along the street")
        if np.any(self.planes[:, 1] <= self.planes[:, 0]):
            raise ValueError("RuntimeStreet: facade_max must be greater than facade_min")

    @property
    def along_coords(self) -> NDArray[np.float64]:
        """``(P,)`` along-street coordinates (m) of the probes, ascending."""
        return self.positions[:, self.along]

    def nearest(self, x: ArrayLike) -> NDArray[np.int64]:
        """Index of the probe nearest to each shading point ``x`` ``(..., 3)`` along the street."""
        return nearest_probe(np.asarray(x, np.float64)[..., self.along], self.along_coords)

    @staticmethod
    def from_manifest(street: manifest.Street, planes: str = "nominal") -> "RuntimeStreet":
        """The runtime street of a manifest street (all its probes; see :class:`StreetProbes`)."""
        return StreetProbes.from_manifest(street).runtime_street(planes)

    def uniforms(self, powers: Sequence[float], origin: ArrayLike | None = None) -> "StreetUniforms":
        """The GLSL uniforms of this street with the lobe table ``powers``, relative to ``origin``
        (default: the street's own, :func:`street_origin`; see :class:`StreetUniforms`)."""
        return StreetUniforms.of(self, powers, origin)


def street_origin(street: RuntimeStreet) -> NDArray[np.float64]:
    """The origin (3,) float64 world m of a street's local frame: the center of its probes' box
    rounded to whole kilometers (:func:`envcap.scene.model.local_origin`, as for meshes), so
    (0, 0, 0) for a street centered within 500 m of the world origin."""
    return local_origin(street.positions.min(axis=0), street.positions.max(axis=0))


def _glsl(type_: str, length: int = 1) -> Any:
    return field(metadata={"glsl": type_, "length": length})


@dataclass(frozen=True)
class StreetUniforms:
    """Mirror of GLSL ``struct EnvcapStreet`` (``shaders/runtime/envcap_runtime.glsl``): one field
    per struct member (:meth:`glsl_fields`), same name, same order; arrays have their full GLSL
    length, zero-padded.  Coordinates are street-local: world meters minus ``origin``, computed in
    float64 and rounded to float32 once.

    * ``along_s`` ``(MAX_PROBES,)`` float32: along-street coordinate of probe i (m), sorted;
    * ``pos`` ``(MAX_PROBES, 4)`` float32: probe i's street-local position (m) in xyz, its cube-array layer in w;
    * ``planes`` ``(MAX_PROBES, 4)`` float32: probe i's (facade_min, facade_max, ground) (m,
      street-local: the facades on the cross axis, the ground on y), w unused;
    * ``count``: number of probes (1..MAX_PROBES); ``along``: street axis, 0 = x, 2 = z;
    * ``xk`` ``(MAX_LEVELS,)`` float32: ``log2(1 + powers[k])``, the z(w) table; ``nlevels``: its length;
    * ``origin`` (3,) float64: world position (m) of the local frame; not a struct member (not
      uploaded): shading points go to GLSL as :meth:`to_local` ``(x)``.

    Each struct member's ``metadata`` holds its GLSL type and array length (``None`` for ``origin``).
    """

    along_s: NDArray[np.float32] = _glsl("float", MAX_PROBES)
    pos: NDArray[np.float32] = _glsl("vec4", MAX_PROBES)
    planes: NDArray[np.float32] = _glsl("vec4", MAX_PROBES)
    count: int = _glsl("int")
    along: int = _glsl("int")
    xk: NDArray[np.float32] = _glsl("float", MAX_LEVELS)
    nlevels: int = _glsl("int")
    origin: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3), metadata={"glsl": None, "length": 3})

    @staticmethod
    def glsl_fields() -> tuple[dataclasses.Field, ...]:
        """The fields that are members of GLSL ``struct EnvcapStreet``, in struct order."""
        return tuple(f for f in dataclasses.fields(StreetUniforms) if f.metadata["glsl"] is not None)

    @staticmethod
    def of(street: RuntimeStreet, powers: Sequence[float], origin: ArrayLike | None = None) -> "StreetUniforms":
        """The uniforms of ``street`` with the lobe table ``powers`` (the manifest's, strictly
        decreasing), relative to ``origin`` (3,) world m (default :func:`street_origin`)."""
        P = street.positions.shape[0]
        xk = lobe_table(powers)
        o = street_origin(street) if origin is None else np.asarray(origin, np.float64).reshape(3)
        if not np.all(np.isfinite(o)):
            raise ValueError(f"street origin must be finite, got {o}")
        c = 2 - street.along

        def padded(a: NDArray, length: int) -> NDArray[np.float32]:
            out = np.zeros((length,) + a.shape[1:], np.float32)
            out[: a.shape[0]] = a.astype(np.float32)
            return out

        # float64 differences, rounded to float32 once (by padded)
        pos = np.concatenate([street.positions - o, street.layers[:, None].astype(np.float64)], axis=1)
        planes = np.concatenate([street.planes - np.array([o[c], o[c], o[1]]), np.zeros((P, 1))], axis=1)
        return StreetUniforms(padded(street.along_coords - o[street.along], MAX_PROBES), padded(pos, MAX_PROBES),
                              padded(planes, MAX_PROBES), int(P), int(street.along), padded(xk, MAX_LEVELS),
                              int(xk.size), o.copy())

    def to_local(self, x: ArrayLike) -> NDArray[np.float32]:
        """World points ``x`` (..., 3) m in this street's local frame, as GLSL takes them:
        ``float32(x - origin)``, the difference computed in float64."""
        return (np.asarray(x, np.float64) - self.origin).astype(np.float32)

    def values(self, uniform: str = GLSL_UNIFORM) -> dict[str, Any]:
        """``{"<uniform>.<member>": value}`` for :func:`envcap.gpu.glsl_harness.set_uniforms`
        (the struct members only: ``origin`` is not uploaded)."""
        return {f"{uniform}.{f.name}": getattr(self, f.name) for f in self.glsl_fields()}


@dataclass(frozen=True)
class StreetProbes:
    """Every probe of one street of a probe set, sorted along the street (any number of them).

    ``positions`` ``(P, 3)`` m; ``layers`` ``(P,)``; ``planes`` ``(P, 3)`` nominal and
    ``fitted_planes`` ``(P, 3)`` fitted (nominal where a plane was not fitted or the fitted
    facades are not ordered).  :meth:`runtime_street` and :meth:`local` cut runtime streets of it.
    """

    name: str
    along: int
    positions: NDArray[np.float64]
    layers: NDArray[np.int64]
    planes: NDArray[np.float64]
    fitted_planes: NDArray[np.float64]

    @staticmethod
    def from_manifest(street: manifest.Street) -> "StreetProbes":
        """The probes of a manifest street (:class:`envcap.probeset.manifest.Street`), sorted
        along it (the runtime's one reader of manifest streets)."""
        probes = street.probes_along()
        if not probes:
            raise ValueError(f"street {street.name!r} has no probes")
        nominal = np.array([q.planes.as_array() for q in probes], dtype=np.float64)
        fitted = nominal.copy()
        for i, q in enumerate(probes):
            if q.fitted_planes is not None:
                fitted[i] = q.fitted_planes.merged(q.planes).as_array()
            if not fitted[i, 1] > fitted[i, 0]:
                fitted[i] = nominal[i]
        return StreetProbes(street.name, street.along_index, np.array([q.position for q in probes], dtype=np.float64),
                            np.array([q.layer for q in probes], dtype=np.int64), nominal, fitted)

    def runtime_street(self, planes: str = "nominal", indices: ArrayLike | None = None) -> RuntimeStreet:
        """The runtime street of the probes ``indices`` (ascending; default all) with the plane set ``planes``."""
        if planes not in PLANE_SETS:
            raise ValueError(f"plane set must be one of {PLANE_SETS}, got {planes!r}")
        idx = np.arange(self.layers.size) if indices is None else np.asarray(indices)
        pl = self.fitted_planes if planes == "fitted" else self.planes
        return RuntimeStreet(self.along, self.positions[idx], pl[idx], self.layers[idx])

    def local(self, x: ArrayLike, count: int, planes: str = "nominal") -> RuntimeStreet:
        """The runtime street of the ``count`` probes nearest to point ``x`` (3,) along the street
        (an engine uploads the neighbourhood: selection and blending only need neighbours)."""
        s = self.positions[:, self.along]
        xs = np.asarray(x, np.float64)[self.along]
        idx = np.sort(np.argsort(np.abs(s - xs), kind="stable")[:count])
        return self.runtime_street(planes, idx)
