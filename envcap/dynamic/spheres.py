"""Many spheres: the sphere buffer, the K most occluding spheres of a shading point, and the rule
that combines their overlapping caps (numpy twin of ``shaders/runtime/envcap_dynamic_spheres.glsl``;
``docs/dynamic.md``, "Many spheres").

* :class:`SphereBuffer`: centers ``(N, 3)`` m, radii ``(N,)`` m, albedo ``(N, 3)`` (linear RGB,
  ``[0, 1]``); as one array ``(N, 7)`` = ``(x, y, z, r, a_r, a_g, a_b)`` (:meth:`as_array`).
* :func:`select_spheres`: per shading point the ``cap`` spheres of largest solid angle (smallest
  lobe power ``t``; ties: lower index first), as lobes ``(D, t)`` (:func:`sphere_lobe`).  Fewer
  spheres than ``cap`` (or radius 0) leave slots with index ``-1`` that block nothing.
* :func:`combine`: the lobe's blocked fraction ``U`` from the per-sphere fractions ``f_k`` and each
  sphere's share.  ``"rings"`` (default): the union merged exactly on a few rings of the lobe
  (:func:`envcap.dynamic.union.ring_union`; needs the caps and the lobe, ``lobe=(D, t, C, w)``);
  ``"overlap"``: inclusion-exclusion to pairs, the lobe's light in the
  intersection of two caps taken as ``min(f_j, f_k) o_jk`` with ``o_jk`` the intersection's
  solid angle over the smaller cap's (:func:`cap_overlap`, closed form), ``U = sum f - sum_{j<k}
  min(f_j, f_k) o_jk`` clamped to ``[max f, 1]``: exact for disjoint caps (the sum) and for nested
  ones (the larger); ``"independent"``: ``U = 1 - prod(1 - f_k)``, the caps as independent random
  occluders; ``"sum"``: ``min(1, sum f_k)``; ``"max"``: ``max f_k``.  Each sphere keeps the
  share ``f_k U / sum f``, so the shares add up to ``U``.  GLSL: ``ENVCAP_DYNAMIC_COMBINE`` 0-4
  in the order of :data:`COMBINE_RULES` (``"rings"`` = 4, the default).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.dynamic.lobe_product import MAX_POWER
from envcap.dynamic.sphere_lobe import sphere_lobe
from envcap.dynamic.union import UNION_NODES, ring_union

SPHERE_CAP = 8
"""Default number of spheres a shading point considers (GLSL ``ENVCAP_SPHERE_CAP``)."""

CombineRule = Literal["overlap", "independent", "sum", "max", "rings"]
"""How overlapping caps combine (module docstring).  GLSL ``ENVCAP_DYNAMIC_COMBINE`` = index."""
DEFAULT_RULE: CombineRule = "rings"
"""The default rule (GLSL ``ENVCAP_DYNAMIC_COMBINE`` 4)."""
COMBINE_RULES: tuple[str, ...] = get_args(CombineRule)


@dataclass(frozen=True)
class SphereBuffer:
    """Spheres: ``centers`` ``(N, 3)`` (m, world), ``radii`` ``(N,)`` (m, >= 0; 0 = an empty
    slot), ``albedo`` ``(N, 3)`` (linear RGB in ``[0, 1]``, what a sphere bounces)."""

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    albedo: NDArray[np.float64]

    def __post_init__(self) -> None:
        c = np.asarray(self.centers, np.float64).reshape(-1, 3)
        r = np.asarray(self.radii, np.float64).reshape(-1)
        a = np.asarray(self.albedo, np.float64)
        a = np.broadcast_to(a, (len(r), 3)).copy() if a.size in (1, 3) and len(r) != 1 else a.reshape(-1, 3)
        if not len(c) == len(r) == len(a):
            raise ValueError(f"SphereBuffer: {len(c)} centers, {len(r)} radii and {len(a)} albedos must match")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r)) and np.all(np.isfinite(a))):
            raise ValueError("SphereBuffer: centers, radii and albedo must be finite")
        if np.any(r < 0):
            raise ValueError(f"SphereBuffer: radii must be >= 0 m, got {r.min():g}")
        if np.any(a < 0) or np.any(a > 1):
            raise ValueError("SphereBuffer: albedo must be in [0, 1]")
        for name, v in (("centers", c), ("radii", r), ("albedo", a)):
            object.__setattr__(self, name, v)

    @classmethod
    def from_array(cls, arr: ArrayLike) -> "SphereBuffer":
        """From ``(N, 7)``: center xyz (m), radius (m), albedo rgb."""
        a = np.asarray(arr, np.float64)
        if a.ndim != 2 or a.shape[1] != 7:
            raise ValueError(f"SphereBuffer.from_array needs shape (N, 7), got {a.shape}")
        return cls(a[:, :3], a[:, 3], a[:, 4:])

    def as_array(self) -> NDArray[np.float64]:
        """``(N, 7)``: center xyz, radius, albedo rgb."""
        return np.c_[self.centers, self.radii, self.albedo]

    def __len__(self) -> int:
        return len(self.radii)


@dataclass(frozen=True)
class Selection:
    """The spheres a shading point considers: ``index`` ``(..., K)`` (-1: empty slot), their lobes
    ``D`` ``(..., K, 3)`` (unit, 0 inside a sphere) and ``t`` ``(..., K)`` (MAX_POWER when empty),
    and ``overlap`` ``(..., K, K)``: :func:`cap_overlap` of each pair (0 on the diagonal)."""

    index: NDArray[np.int64]
    D: NDArray
    t: NDArray
    overlap: NDArray


def cap_overlap(theta1: ArrayLike, theta2: ArrayLike, beta: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Solid angle of the intersection of two caps (half-angles ``theta1``, ``theta2``, axes
    ``beta`` apart; rad, ``(...)``) over the smaller cap's: 0 when disjoint, 1 when nested, else
    ``2 (pi - a - b cos theta1 - c cos theta2) / Omega_min`` with ``cos a = (cos beta - cos theta1
    cos theta2) / (sin theta1 sin theta2)``, ``cos b = (cos theta2 - cos beta cos theta1) / (sin
    beta sin theta1)``, ``cos c`` likewise (the spherical triangle of the two axes and a corner
    of the lens).  ``acos`` as ``atan2`` (GPU ``acos`` is poor)."""
    t1, t2, be = np.broadcast_arrays(*(np.asarray(a, dtype=dtype) for a in (theta1, theta2, beta)))
    c1, c2, cb = np.cos(t1), np.cos(t2), np.cos(be)
    s1, s2, sb = np.sin(t1), np.sin(t2), np.sin(be)

    def acos_ratio(num: NDArray, den: NDArray) -> NDArray:
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.clip(np.where(den > 0, num / np.where(den > 0, den, dtype(1)), dtype(1)), dtype(-1), dtype(1))
        return np.arctan2(np.sqrt(np.maximum((dtype(1) - x) * (dtype(1) + x), dtype(0))), x)

    a = acos_ratio(cb - c1 * c2, s1 * s2)
    b = acos_ratio(c2 - cb * c1, sb * s1)
    c = acos_ratio(c1 - cb * c2, sb * s2)
    lens = dtype(2) * (dtype(np.pi) - a - b * c1 - c * c2)
    small = dtype(2 * np.pi) * (dtype(1) - np.maximum(c1, c2))
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(small > 0, np.clip(lens, dtype(0), small) / np.where(small > 0, small, dtype(1)), dtype(0))
    frac = np.where(be >= t1 + t2, dtype(0), np.where(be <= np.abs(t1 - t2), dtype(1), frac))
    return frac.astype(dtype)


def select_spheres(x: ArrayLike, spheres: SphereBuffer, cap: int = SPHERE_CAP, dtype: Any = np.float64,
                   normal: ArrayLike | None = None) -> Selection:
    """The ``cap`` spheres of largest solid angle seen from each point ``x`` ``(..., 3)`` (m).

    With ``normal`` ``(..., 3)`` (unit, or zero: no test), spheres wholly below the point's
    horizon (``D . N <= -sin(theta)``, ``theta`` the cap's half-angle) block nothing the lobes see
    and are not ranked: they would otherwise take the slots of the ones in front."""
    if int(cap) < 1:
        raise ValueError(f"the sphere cap must be >= 1, got {cap}")
    x = np.asarray(x, dtype=dtype)
    shp = x.shape[:-1]
    K, n = int(cap), len(spheres)
    index = np.full(shp + (K,), -1, dtype=np.int64)
    D = np.zeros(shp + (K, 3), dtype=dtype)
    D[..., 2] = 1
    t = np.full(shp + (K,), dtype(MAX_POWER), dtype=dtype)
    if n == 0:
        return Selection(index, D, t, np.zeros(shp + (K, K), dtype=dtype))
    Dn, tn = sphere_lobe(x[..., None, :], spheres.centers.astype(dtype), spheres.radii.astype(dtype), dtype=dtype)
    live = np.broadcast_to(spheres.radii > 0, tn.shape)
    if normal is not None:
        nrm = np.asarray(normal, dtype=dtype)[..., None, :]
        half = np.arctan2(np.sqrt(dtype(1) + dtype(2) * tn), tn)      # cap_lobe.cap_half_angle
        live = live & (np.sum(Dn * nrm, axis=-1) > -np.sin(half))
    key = np.where(live, tn, np.inf)
    order = np.argsort(key, axis=-1, kind="stable")[..., :K]
    k = order.shape[-1]
    got = np.take_along_axis(live, order, axis=-1)
    index[..., :k] = np.where(got, order, -1)
    D[..., :k, :] = np.where(got[..., None], np.take_along_axis(Dn, order[..., None], axis=-2), D[..., :k, :])
    t[..., :k] = np.where(got, np.take_along_axis(tn, order, axis=-1), t[..., :k])
    theta = np.arctan2(np.sqrt(dtype(1) + dtype(2) * t), t)          # cap_lobe.cap_half_angle
    cosb = np.einsum("...ji,...ki->...jk", D, D)
    beta = np.arctan2(np.linalg.norm(np.cross(D[..., :, None, :], D[..., None, :, :]), axis=-1), cosb)
    ov = cap_overlap(theta[..., :, None], theta[..., None, :], beta, dtype)
    live = index >= 0
    ov = np.where(live[..., :, None] & live[..., None, :] & ~np.eye(K, dtype=bool), ov, dtype(0))
    return Selection(index, D, t, ov.astype(dtype))


def check_rule(rule: str) -> None:
    """A clear error for an unknown :data:`CombineRule`."""
    if rule not in COMBINE_RULES:
        raise ValueError(f"sphere combine rule must be one of {COMBINE_RULES}, got {rule!r}")


def combine(f: ArrayLike, rule: CombineRule = DEFAULT_RULE, overlap: ArrayLike | None = None,
            dtype: Any = np.float64, *, lobe: tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike] | None = None,
            nodes: int = UNION_NODES) -> tuple[NDArray, NDArray]:
    """``(U, share)``: the union's blocked fraction ``U`` ``(...)`` of per-sphere fractions ``f``
    ``(..., K)`` in ``[0, 1]``, and each sphere's share ``(..., K)`` (sums to ``U``).
    ``overlap``: ``(..., K, K)`` (:attr:`Selection.overlap`), needed by ``"overlap"``; ``lobe``:
    ``(D (..., K, 3), t (..., K), C (..., 3), w (...))``, the selected spheres' lobes
    (:attr:`Selection.D`, :attr:`Selection.t`) and the BRDF lobe's axis and power, needed by
    ``"rings"`` (with ``nodes`` rings, 1..8)."""
    check_rule(rule)
    f = np.clip(np.asarray(f, dtype=dtype), dtype(0), dtype(1))
    total = np.sum(f, axis=-1, dtype=dtype)
    if rule == "rings":
        if lobe is None:
            raise ValueError("the 'rings' combine rule needs the lobes (D, t, C, w): combine(..., lobe=...)")
        D, t, C, w = lobe
        U = ring_union(D, t, C, w, f, nodes, dtype)
    elif rule == "overlap":
        if overlap is None:
            raise ValueError("the 'overlap' combine rule needs the pairs' overlap (Selection.overlap)")
        o = np.triu(np.asarray(overlap, dtype=dtype), 1)
        pair = np.minimum(f[..., :, None], f[..., None, :]) * o
        U = np.clip(total - np.sum(pair, axis=(-2, -1), dtype=dtype), np.max(f, axis=-1), dtype(1))
    elif rule == "independent":
        U = dtype(1) - np.prod(dtype(1) - f, axis=-1, dtype=dtype)
    elif rule == "sum":
        U = np.minimum(total, dtype(1))
    else:
        U = np.max(f, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(total > 0, U / np.where(total > 0, total, dtype(1)), dtype(0))
    return U.astype(dtype), (f * scale[..., None]).astype(dtype)
