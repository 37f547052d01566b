"""Streets as the runtime sees them: the probes of a street, the runtime street (at most
``MAX_PROBES`` probes, what one draw uploads) and its GLSL uniforms.

The uniforms are one GLSL struct, ``EnvcapStreet`` (``shaders/runtime/envcap_street.glsl``),
declared as ``uniform EnvcapStreet envcap_street;`` by ``envcap_street_uniforms.glsl``;
:class:`StreetUniforms` mirrors it field for field (``tests/runtime/test_street_uniforms.py``
compiles the GLSL and checks names, types and lengths, and reads the values back).

Conventions: meters, +Y up, in the street's frame (:mod:`envcap.core.street_frame`: the world
for a street along x or z; for a street at any angle, world points turned by its ``yaw_deg``
about its plan point ``origin_xz``); a street runs along axis ``along`` (0 = x, 2 = z) of its
frame; ``planes`` per probe are ``(facade_min, facade_max, ground)`` in absolute frame coordinates
(m), ``slopes`` the ground's rise per meter along the street (through ``ground`` at the probe).
The uniforms are street-local: frame coordinates minus the street's ``origin`` (float64, kept on
:class:`StreetUniforms`, not uploaded), computed in float64 and rounded to float32 once, so that
a street 10^6 m from the world origin samples like the same street at the origin.  Lookups take
world points and directions: the runtime turns them into the frame (GLSL: ``EnvcapStreet.frame``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.street_frame import to_frame, world_to_frame, yaw_cos_sin
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

    ``along``: axis index of the street in its frame (0 = x, 2 = z).  ``positions``: ``(P, 3)``
    probe positions (m, frame coordinates), sorted along the street; ``planes``: ``(P, 3)``
    (facade_min, facade_max, ground) per probe (m, frame); ``layers``: ``(P,)`` cube-array layer of
    each probe.  ``yaw_deg``, ``origin_xz``: the street's frame (:mod:`envcap.core.street_frame`;
    0 and (0, 0): the world, today's streets); a framed street has ``along = 0``.  ``slopes``:
    ``(P,)`` rise of the ground (m per m) along the street through ``ground`` at each probe
    (default zeros: a horizontal ground).
    """

    along: int
    positions: NDArray[np.float64]
    planes: NDArray[np.float64]
    layers: NDArray[np.int64]
    yaw_deg: float = 0.0
    origin_xz: tuple[float, float] = (0.0, 0.0)
    slopes: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        check_along(self.along)
        P = self.positions.shape[0]
        slopes = np.zeros(P) if self.slopes is None else np.asarray(self.slopes, np.float64)
        object.__setattr__(self, "slopes", slopes)
        object.__setattr__(self, "origin_xz", (float(self.origin_xz[0]), float(self.origin_xz[1])))
        world_to_frame(np.zeros(3), self.yaw_deg, self.origin_xz)      # checks yaw and origin
        if slopes.shape != (P,) or not np.all(np.isfinite(slopes)):
            raise ValueError(f"RuntimeStreet: slopes must be ({P},) finite numbers")
        if self.framed and self.along != 0:
            raise ValueError("RuntimeStreet: a street with its own frame runs along the frame's x (along = 0)")
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
    def framed(self) -> bool:
        """Whether the street has its own frame (a yaw or a plan origin other than 0)."""
        return float(self.yaw_deg) != 0.0 or self.origin_xz != (0.0, 0.0)

    @property
    def frame(self) -> NDArray[np.float64]:
        """``(cos yaw, sin yaw)`` (GLSL ``EnvcapStreet.frame``), float64."""
        c, s = yaw_cos_sin(float(self.yaw_deg))
        return np.array([float(c), float(s)])

    def to_frame(self, x: ArrayLike) -> NDArray[np.float64]:
        """World points ``x`` (..., 3) in the street's frame (float64; unchanged when not framed)."""
        return world_to_frame(x, self.yaw_deg, self.origin_xz)

    def direction_to_frame(self, d: ArrayLike) -> NDArray[np.float64]:
        """World directions ``d`` (..., 3) in the street's frame (float64; unchanged without a yaw)."""
        return to_frame(d, self.yaw_deg) if self.yaw_deg else np.asarray(d, np.float64)

    @property
    def lookup_planes(self) -> NDArray[np.float64]:
        """The planes the parallax functions take (:mod:`envcap.runtime.parallax`): ``planes``
        ``(P, 3)`` when the ground is horizontal everywhere, else ``(P, 4)`` ``(facade_min,
        facade_max, ground at along 0, slope)``."""
        if not np.any(self.slopes):
            return self.planes
        g0 = self.planes[:, 2] - self.slopes * self.along_coords
        return np.concatenate([self.planes[:, :2], g0[:, None], self.slopes[:, None]], axis=1)

    @property
    def along_coords(self) -> NDArray[np.float64]:
        """``(P,)`` along-street coordinates (m) of the probes, ascending."""
        return self.positions[:, self.along]

    def nearest(self, x: ArrayLike) -> NDArray[np.int64]:
        """Index of the probe nearest to each shading point ``x`` ``(..., 3)`` (frame coordinates)
        along the street."""
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
    """The origin (3,) float64 m (street-frame coordinates: the world's for a street without a
    frame) of a street's local frame: the center of its probes' box rounded to whole kilometers
    (:func:`envcap.scene.model.local_origin`, as for meshes), so (0, 0, 0) for a street centered
    within 500 m of its frame's origin."""
    return local_origin(street.positions.min(axis=0), street.positions.max(axis=0))


def _glsl(type_: str, length: int = 1) -> Any:
    return field(metadata={"glsl": type_, "length": length})


@dataclass(frozen=True)
class StreetUniforms:
    """Mirror of GLSL ``struct EnvcapStreet`` (``shaders/runtime/envcap_runtime.glsl``): one field
    per struct member (:meth:`glsl_fields`), same name, same order; arrays have their full GLSL
    length, zero-padded.  Coordinates are street-local: frame meters minus ``origin``, computed in
    float64 and rounded to float32 once.

    * ``along_s`` ``(MAX_PROBES,)`` float32: along-street coordinate of probe i (m), sorted;
    * ``pos`` ``(MAX_PROBES, 4)`` float32: probe i's street-local position (m) in xyz, its cube-array layer in w;
    * ``planes`` ``(MAX_PROBES, 4)`` float32: probe i's (facade_min, facade_max, ground0, slope)
      (m, street-local: the facades on the cross axis; the ground's height ``ground0 + slope * s``
      at street-local along coordinate ``s``, so ``ground0`` is the probe's ground for slope 0);
    * ``count``: number of probes (1..MAX_PROBES); ``along``: street axis, 0 = x, 2 = z;
    * ``xk`` ``(MAX_LEVELS,)`` float32: ``log2(1 + powers[k])``, the z(w) table; ``nlevels``: its length;
    * ``frame`` (2,) float32: ``(cos yaw, sin yaw)`` of the street's frame ((1, 0) for the world):
      GLSL turns lookup directions into the frame with it (probe fetches), the sky keeps the world's;
    * ``origin`` (3,) float64: position (m, street frame) of the local frame; ``yaw_deg``,
      ``origin_xz``: the street's frame; not struct members (not uploaded): shading points go to
      GLSL as :meth:`to_local` ``(x)``.

    Each struct member's ``metadata`` holds its GLSL type and array length (``None`` for ``origin``).
    """

    along_s: NDArray[np.float32] = _glsl("float", MAX_PROBES)
    pos: NDArray[np.float32] = _glsl("vec4", MAX_PROBES)
    planes: NDArray[np.float32] = _glsl("vec4", MAX_PROBES)
    count: int = _glsl("int")
    along: int = _glsl("int")
    xk: NDArray[np.float32] = _glsl("float", MAX_LEVELS)
    nlevels: int = _glsl("int")
    frame: NDArray[np.float32] = _glsl("vec2")
    origin: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3), metadata={"glsl": None, "length": 3})
    yaw_deg: float = field(default=0.0, metadata={"glsl": None, "length": 1})
    origin_xz: tuple[float, float] = field(default=(0.0, 0.0), metadata={"glsl": None, "length": 2})

    @staticmethod
    def glsl_fields() -> tuple[dataclasses.Field, ...]:
        """The fields that are members of GLSL ``struct EnvcapStreet``, in struct order."""
        return tuple(f for f in dataclasses.fields(StreetUniforms) if f.metadata["glsl"] is not None)

    @staticmethod
    def of(street: RuntimeStreet, powers: Sequence[float], origin: ArrayLike | None = None) -> "StreetUniforms":
        """The uniforms of ``street`` with the lobe table ``powers`` (the manifest's, strictly
        decreasing), relative to ``origin`` (3,) m in the street's frame (default :func:`street_origin`)."""
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
        k = street.slopes
        if np.any(k):      # the ground's height at street-local along coordinate 0
            planes[:, 2] -= k * (street.along_coords - o[street.along])
            planes[:, 3] = k
        return StreetUniforms(padded(street.along_coords - o[street.along], MAX_PROBES), padded(pos, MAX_PROBES),
                              padded(planes, MAX_PROBES), int(P), int(street.along), padded(xk, MAX_LEVELS),
                              int(xk.size), street.frame.astype(np.float32), o.copy(), float(street.yaw_deg),
                              street.origin_xz)

    def to_local(self, x: ArrayLike) -> NDArray[np.float32]:
        """World points ``x`` (..., 3) m in this street's local frame, as GLSL takes them:
        ``float32(world_to_frame(x) - origin)``, computed in float64 (for a street without a frame
        ``float32(x - origin)``)."""
        return (world_to_frame(x, self.yaw_deg, self.origin_xz) - self.origin).astype(np.float32)

    def values(self, uniform: str = GLSL_UNIFORM) -> dict[str, Any]:
        """``{"<uniform>.<member>": value}`` for :func:`envcap.gpu.glsl_harness.set_uniforms`
        (the struct members only: ``origin`` is not uploaded)."""
        return {f"{uniform}.{f.name}": getattr(self, f.name) for f in self.glsl_fields()}


@dataclass(frozen=True)
class StreetProbes:
    """Every probe of one street of a probe set, sorted along the street (any number of them).

    ``positions`` ``(P, 3)`` m (the street's frame); ``layers`` ``(P,)``; ``planes`` ``(P, 3)``
    nominal and ``fitted_planes`` ``(P, 3)`` fitted (nominal where a plane was not fitted or the
    fitted facades are not ordered), ``slopes`` / ``fitted_slopes`` ``(P,)`` their ground slopes;
    ``yaw_deg``, ``origin_xz``: the street's frame (as :class:`RuntimeStreet`).
    :meth:`runtime_street` and :meth:`local` cut runtime streets of it.
    """

    name: str
    along: int
    positions: NDArray[np.float64]
    layers: NDArray[np.int64]
    planes: NDArray[np.float64]
    fitted_planes: NDArray[np.float64]
    yaw_deg: float = 0.0
    origin_xz: tuple[float, float] = (0.0, 0.0)
    slopes: NDArray[np.float64] | None = None
    fitted_slopes: NDArray[np.float64] | None = None

    @staticmethod
    def from_manifest(street: manifest.Street) -> "StreetProbes":
        """The probes of a manifest street (:class:`envcap.probeset.manifest.Street`), sorted
        along it (the runtime's one reader of manifest streets)."""
        probes = street.probes_along()
        if not probes:
            raise ValueError(f"street {street.name!r} has no probes")
        nominal = np.array([q.planes.as_array() for q in probes], dtype=np.float64)
        slopes = np.array([q.planes.slope for q in probes], dtype=np.float64)
        fitted, fitted_slopes = nominal.copy(), slopes.copy()
        for i, q in enumerate(probes):
            if q.fitted_planes is not None:
                merged = q.fitted_planes.merged(q.planes)
                fitted[i], fitted_slopes[i] = merged.as_array(), merged.slope
            if not fitted[i, 1] > fitted[i, 0]:
                fitted[i], fitted_slopes[i] = nominal[i], slopes[i]
        yaw, oxz = street.frame_yaw_deg, street.frame_origin_xz
        pos = street.frame_positions(probes)
        return StreetProbes(street.name, street.along_index, pos, np.array([q.layer for q in probes], dtype=np.int64),
                            nominal, fitted, yaw, oxz, slopes, fitted_slopes)

    def runtime_street(self, planes: str = "nominal", indices: ArrayLike | None = None) -> RuntimeStreet:
        """The runtime street of the probes ``indices`` (ascending; default all) with the plane set ``planes``."""
        if planes not in PLANE_SETS:
            raise ValueError(f"plane set must be one of {PLANE_SETS}, got {planes!r}")
        idx = np.arange(self.layers.size) if indices is None else np.asarray(indices)
        pl = self.fitted_planes if planes == "fitted" else self.planes
        sl = self.fitted_slopes if planes == "fitted" else self.slopes
        return RuntimeStreet(self.along, self.positions[idx], pl[idx], self.layers[idx], self.yaw_deg, self.origin_xz,
                             None if sl is None else sl[idx])

    def local(self, x: ArrayLike, count: int, planes: str = "nominal") -> RuntimeStreet:
        """The runtime street of the ``count`` probes nearest to the WORLD point ``x`` (3,) along the
        street (an engine uploads the neighbourhood: selection and blending only need neighbours)."""
        s = self.positions[:, self.along]
        xs = world_to_frame(np.asarray(x, np.float64), self.yaw_deg, self.origin_xz)[self.along]
        idx = np.sort(np.argsort(np.abs(s - xs), kind="stable")[:count])
        return self.runtime_street(planes, idx)
