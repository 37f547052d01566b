"""The footprint of a cosine lobe on the hit plane, seen from the probe (twin of
``envcap_footprint`` in ``shaders/runtime/envcap_street.glsl``): the oblique, anisotropic mip
shift.

A cos^w lobe around ``d`` from the shading point ``x`` has the angular covariance ``s^2 I``
(per axis, ``s^2 ~ 1/(w + 2)``).  It lands on the plane the ray ``x + t d`` hits as an ellipse:
semi-axes ``t s / cos(alpha)`` along the plane's direction of ``d`` and ``t s`` across it
(``cos(alpha) = |n . d|``).  Seen from the probe ``p`` at ``d_p = |h - p|`` the ellipse projects
onto the plane perpendicular to ``r = (h - p) / d_p``: an angular covariance
``s^2 G`` with principal values ``s^2 g_major >= s^2 g_minor``,
``sqrt(g_major g_minor) = (t / d_p)^2 cos(beta) / cos(alpha)``, ``cos(beta) = |n . r|``.  A lobe
of the probe's chain with the same per-axis variance along an axis has power ``w / g`` there, so:

* the **oblique (area-matched) shift**: ``w' = w q_iso``,
  ``q_iso = (d_p / t)^2 cos(alpha) / cos(beta)`` (the paper's ``(d_p / t)^2`` is the case
  ``alpha = beta``);
* the **anisotropic** footprint: powers ``w q_minor`` across and ``w q_major`` along its long
  axis ``major`` (a unit vector perpendicular to ``r``), ``q = 1 / g``.

Every ``q`` is clamped to ``[1 / MAX_RATIO^2, MAX_RATIO^2]`` like the paper's ratio.  Derivation
and fallbacks: ``docs/runtime.md`` ("Oblique, anisotropic mip shift").  Conventions as
:mod:`envcap.runtime.parallax` (world meters, +Y up, ``planes = (facade_min, facade_max,
ground)``); vectorized, float64 by default, ``dtype=np.float32`` in the GLSL operation order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.runtime.glsl_math import dot3
from envcap.runtime.limits import FAR, MAX_RATIO, MIN_DIST
from envcap.runtime.parallax import check_along, clamp_to_street, exit_distance, parallax, plane_exits, plane_hit, tilted

MIN_COS = 1.0e-4
"""Cosines of the hit angles below this are taken as this (grazing hits; the shift then clamps).
GLSL ``ENVCAP_MIN_COS``."""


@dataclass(frozen=True)
class Footprint:
    """The lobe's footprint seen from the probe, for each lookup (arrays broadcast to ``(...)``).

    ``r`` ``(..., 3)``: unit vector from the probe to the hit point (as :func:`parallax`);
    ``ratio``: ``d_p / t`` clamped (as :func:`parallax`); ``q_iso``, ``q_minor``, ``q_major``:
    power multipliers (``w' = w q``) of the area-matched lobe, of the footprint's short axis and
    of its long axis (``q_minor >= q_iso >= q_major``); ``major`` ``(..., 3)``: unit long axis,
    perpendicular to ``r``.  Fallbacks (no hit, hit at the probe) are isotropic with
    ``q = ratio^2``.
    """

    r: NDArray
    ratio: NDArray
    q_iso: NDArray
    q_minor: NDArray
    q_major: NDArray
    major: NDArray


def hit_normal(x: ArrayLike, d: ArrayLike, planes: ArrayLike, along: int, dtype: Any = np.float64) -> NDArray:
    """Unit normal ``(..., 3)`` (sign irrelevant) of the plane the ray from ``x`` (inside the
    street) along ``d`` exits through: the ground when its exit distance is the smaller one
    (``t_g < t_c``; +y, or ``(-slope, 1, 0) / sqrt(1 + slope^2)`` in (along, y, cross) for a tilted
    ground), else the facades (the cross axis).  No hit: the facades' normal."""
    c = 2 - check_along(along)
    x, d, planes = (np.asarray(a, dtype=dtype) for a in (x, d, planes))
    shape = np.broadcast_shapes(x.shape, d.shape, planes.shape[:-1] + (3,))
    x, d = np.broadcast_to(x, shape), np.broadcast_to(d, shape)
    planes = np.broadcast_to(planes, shape[:-1] + planes.shape[-1:])
    tc, tg = plane_exits(x, d, planes, along, dtype)
    ground = tg < tc
    n = np.zeros(x.shape, dtype=dtype)
    if tilted(planes):
        k = planes[..., 3]
        gl = np.sqrt(dtype(1) + k * k)
        n[..., 1] = np.where(ground, dtype(1) / gl, 0)
        n[..., along] = np.where(ground, -k / gl, 0)
    else:
        n[..., 1] = np.where(ground, 1, 0)
    n[..., c] = np.where(ground, 0, 1)
    return n


def footprint(x: ArrayLike, d: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int,
              dtype: Any = np.float64) -> Footprint:
    """The footprint (:class:`Footprint`) of lobes around unit ``d`` from shading points ``x`` on
    the three planes of the probe at ``p`` (all broadcast; vectors ``(..., 3)``; meters)."""
    xc, d, p, planes, t, hit, rv, dp, ok = plane_hit(x, d, p, planes, along, dtype)
    one = dtype(1)
    n = hit_normal(xc, d, planes, along, dtype)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        ratio = np.minimum(np.maximum(dp / np.maximum(t, dtype(MIN_DIST)), dtype(1.0 / MAX_RATIO)), dtype(MAX_RATIO))
        r = rv / np.where(ok, dp, one)[..., None]
        # in-plane direction of d (ed) and the in-plane axis across it (ep = n x ed)
        dn = dot3(d, n)
        ev = d - dn[..., None] * n
        el = np.sqrt(dot3(ev, ev))
        # d along the normal: any in-plane axis (the footprint is round on the plane); the rolled
        # normal is in the plane of an axis normal, projected into a tilted ground's
        alt = np.roll(n, 1, axis=-1)
        alt = alt - dot3(alt, n)[..., None] * n
        alt = alt / np.sqrt(dot3(alt, alt))[..., None]
        ed = np.where((el > dtype(1e-6))[..., None], ev / np.where(el > dtype(1e-6), el, one)[..., None], alt)
        ep = np.cross(n, ed)
        ca = np.maximum(np.abs(dn), dtype(MIN_COS))
        cb = np.maximum(np.abs(dot3(r, n)), dtype(MIN_COS))
        b1 = dot3(ed, r)
        b2 = dot3(ep, r)
        k = one / (ratio * ratio)                      # (t / d_p)^2
        g11 = k * (one - b1 * b1) / (ca * ca)
        g22 = k * (one - b2 * b2)
        g12 = -k * (b1 * b2) / ca
        half = dtype(0.5) * (g11 + g22)
        gmaj = half + np.sqrt(dtype(0.25) * (g11 - g22) * (g11 - g22) + g12 * g12)
        q_iso = ratio * ratio * (ca / cb)                 # 1 / sqrt(det G)
        # long axis: the eigenvector of G for gmaj in the basis (v1, v2), v1 = (ed - b1 r) / ca,
        # v2 = ep - b2 r (the plane's ellipse axes projected across r)
        first = g11 >= g22
        u1 = np.where(first, gmaj - g22, g12)
        u2 = np.where(first, g12, gmaj - g11)
        round_ = (u1 == 0) & (u2 == 0)                    # a round footprint: any axis
        u1 = np.where(round_, one, u1)
        mv = (u1 / ca)[..., None] * (ed - b1[..., None] * r) + u2[..., None] * (ep - b2[..., None] * r)
        ml = np.sqrt(dot3(mv, mv))
    lo, hi = dtype(1.0 / (MAX_RATIO * MAX_RATIO)), dtype(MAX_RATIO * MAX_RATIO)
    fb = np.where(hit, lo, one)                           # the parallax fallbacks: ratio^2
    q_iso = np.where(ok, np.minimum(np.maximum(q_iso, lo), hi), fb)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        q_major = np.where(ok, np.minimum(np.maximum(one / gmaj, lo), hi), fb)
        q_minor = np.where(ok, np.minimum(np.maximum(q_iso * q_iso / q_major, lo), hi), fb)
    r_out = np.where(ok[..., None], r, d)
    ratio_out = np.where(ok, ratio, np.where(hit, dtype(1.0 / MAX_RATIO), one))
    axis = any_perpendicular(r_out, dtype)
    good = ok & (ml > 0)
    major = np.where(good[..., None], mv / np.where(good, ml, one)[..., None], axis)
    return Footprint(r_out.astype(dtype), ratio_out.astype(dtype), q_iso.astype(dtype), q_minor.astype(dtype),
                     q_major.astype(dtype), major.astype(dtype))


def any_perpendicular(v: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """A unit vector ``(..., 3)`` perpendicular to unit ``v``: ``normalize(cross(v, e))`` with
    ``e`` the axis of ``v``'s smallest component (x, then y, then z on ties)."""
    v = np.asarray(v, dtype=dtype)
    a = np.abs(v)
    ex = (a[..., 0] <= a[..., 1]) & (a[..., 0] <= a[..., 2])
    ey = ~ex & (a[..., 1] <= a[..., 2])
    e = np.zeros(v.shape, dtype=dtype)
    e[..., 0] = np.where(ex, 1, 0)
    e[..., 1] = np.where(ey, 1, 0)
    e[..., 2] = np.where(ex | ey, 0, 1)
    c = np.cross(v, e).astype(dtype)
    cl = np.sqrt(dot3(c, c))
    return c / np.where(cl > 0, cl, dtype(1))[..., None]


def tap_offsets(taps: int) -> NDArray[np.float64]:
    """Offsets ``c_i`` (in units of ``sqrt(g_major - g_tap)``) of ``taps`` equally spaced taps
    along the long axis, centred, with mean square 1: ``c_i = (i - (taps - 1)/2) sqrt(12 / (taps^2 - 1))``."""
    if taps < 1:
        raise ValueError(f"need at least 1 tap, got {taps}")
    if taps == 1:
        return np.zeros(1)
    i = np.arange(taps, dtype=np.float64)
    return (i - 0.5 * (taps - 1)) * np.sqrt(12.0 / (taps * taps - 1.0))


SPREAD = 1.3
"""Offset of the four sigma rays of :func:`sigma_footprint`, in units of the lobe's RMS tangent
``sqrt(2 / (w + 3))`` (1 would be exact for a linear map; 1.3 matches the cos^w lobe's heavy
tail best against the float64 reference, ``envcap bench mipshift``).  GLSL ``ENVCAP_SPREAD``."""


@dataclass(frozen=True)
class SigmaFootprint:
    """The footprint measured by four sigma rays (:func:`sigma_footprint`); arrays ``(...)``.

    ``r`` ``(..., 3)`` and ``ratio``: as :func:`envcap.runtime.parallax.parallax`;
    ``var_major >= var_minor``: per-axis variances of the sine of the angle to ``r`` seen from the
    probe (a cos^W lobe has ``1 / (W + 3)``); ``major`` ``(..., 3)``: unit long axis, perpendicular
    to ``r``.  :meth:`power` is the area-matched lobe power ``1 / sqrt(var_major var_minor) - 3``.
    """

    r: NDArray
    ratio: NDArray
    var_minor: NDArray
    var_major: NDArray
    major: NDArray
    rays: NDArray
    """``(..., 4, 3)``: the four sigma rays' hits seen from the probe (unit; a ray that hits no plane: its own direction)."""

    def power(self) -> NDArray:
        """Area-matched lobe power ``max(1 / sqrt(var_minor var_major) - 3, 0)`` (``inf`` for a
        point footprint: the mirror)."""
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return np.maximum(np.reciprocal(np.sqrt(self.var_minor * self.var_major)) - 3, 0)


def sigma_footprint(x: ArrayLike, d: ArrayLike, w: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int,
                    dtype: Any = np.float64) -> SigmaFootprint:
    """The footprint of the cos^w lobe around unit ``d`` from ``x`` seen from the probe at ``p``,
    measured by tracing four sigma rays through the three planes (broadcast; vectors ``(..., 3)``).

    Rays ``normalize(d +- a e_j)``, ``a = SPREAD sqrt(2 / (w + 3))``, ``(e_1, e_2)`` a basis across
    ``d`` (``e_1 = normalize(d x X)``, ``X`` = +x, or +y when ``|d_x| >= 0.9``; ``e_2 = d x e_1``), hit
    the planes (or the sky: their own direction) and are seen from the probe as unit ``v_i``; their
    second moments across ``r`` (basis ``f_1 = normalize(r x X')``, ``f_2 = r x f_1``, ``X'`` chosen
    like ``X`` for ``r``), times ``(1 + a^2) / SPREAD^2`` (the rays' sine is ``a / sqrt(1 + a^2)``),
    are the footprint's covariance.  Exact for a linear map; the corners of the street, the spill
    onto another plane and obliquity are traced, not approximated.  ``w = inf``: a point footprint.
    """
    x, d, p, planes = (np.asarray(a, dtype=dtype) for a in (x, d, p, planes))
    w = np.asarray(w, dtype=dtype)
    shape = np.broadcast_shapes(x.shape, d.shape, p.shape, planes.shape[:-1] + (3,), w.shape + (3,))
    x, d, p = (np.broadcast_to(a, shape) for a in (x, d, p))
    planes = np.broadcast_to(planes, shape[:-1] + planes.shape[-1:])
    w = np.broadcast_to(np.where(w > 0, w, dtype(0)), shape[:-1])   # w < 0 and NaN count as 0
    one = dtype(1)
    xc = clamp_to_street(x, planes, along, dtype)
    r, ratio = parallax(x, d, p, planes, along, dtype)               # the central ray, as the runtime's
    e1, e2 = _basis(d, dtype)
    f1, f2 = _basis(r, dtype)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        a = dtype(SPREAD) * np.sqrt(dtype(2) / (w + dtype(3)))
    cs, rays = [], []
    for e, sg in ((e1, 1), (e1, -1), (e2, 1), (e2, -1)):
        u = d + (dtype(sg) * a)[..., None] * e
        u = u / np.sqrt(dot3(u, u))[..., None]
        tu = exit_distance(xc, u, planes, along, dtype)
        v = (xc - p) + tu[..., None] * u
        vl = np.sqrt(dot3(v, v))
        good = (tu < dtype(FAR)) & (vl > dtype(MIN_DIST))
        v = np.where(good[..., None], v / np.where(good, vl, one)[..., None], u)
        cs.append((dot3(v, f1), dot3(v, f2)))
        rays.append(v)
    k = dtype(0.25) * (one + a * a) / dtype(SPREAD * SPREAD)
    s11 = k * (((cs[0][0] * cs[0][0] + cs[1][0] * cs[1][0]) + cs[2][0] * cs[2][0]) + cs[3][0] * cs[3][0])
    s22 = k * (((cs[0][1] * cs[0][1] + cs[1][1] * cs[1][1]) + cs[2][1] * cs[2][1]) + cs[3][1] * cs[3][1])
    s12 = k * (((cs[0][0] * cs[0][1] + cs[1][0] * cs[1][1]) + cs[2][0] * cs[2][1]) + cs[3][0] * cs[3][1])
    # det by Cauchy-Binet, a sum of squares (no cancellation for thin footprints near a plane)
    det = np.zeros(shape[:-1], dtype)
    for i in range(4):
        for j in range(i + 1, 4):
            c = cs[i][0] * cs[j][1] - cs[i][1] * cs[j][0]
            det = det + c * c
    det = (k * k) * det
    half = dtype(0.5) * (s11 + s22)
    vmaj = half + np.sqrt(dtype(0.25) * (s11 - s22) * (s11 - s22) + s12 * s12)
    with np.errstate(invalid="ignore", divide="ignore"):
        vmin = np.where(vmaj > 0, np.minimum(det / np.where(vmaj > 0, vmaj, one), vmaj), dtype(0))
    first = s11 >= s22
    u1 = np.where(first, vmaj - s22, s12)
    u2 = np.where(first, s12, vmaj - s11)
    big = np.maximum(np.abs(u1), np.abs(u2))           # scaled first: the components may underflow when squared
    u1 = np.where(big > 0, u1 / np.where(big > 0, big, one), one)
    u2 = np.where(big > 0, u2 / np.where(big > 0, big, one), dtype(0))
    m = u1[..., None] * f1 + u2[..., None] * f2
    m = m / np.sqrt(dot3(m, m))[..., None]
    return SigmaFootprint(r.astype(dtype), ratio.astype(dtype), vmin.astype(dtype), vmaj.astype(dtype), m.astype(dtype),
                          np.stack(rays, axis=-2).astype(dtype))


def _basis(v: NDArray, dtype: Any) -> tuple[NDArray, NDArray]:
    """``(e_1, e_2)`` across unit ``v``: ``e_1 = normalize(v x X)``, ``X`` = +x (+y when ``|v_x| >= 0.9``), ``e_2 = v x e_1``."""
    X = np.zeros(v.shape, dtype)
    sel = np.abs(v[..., 0]) < dtype(0.9)
    X[..., 0] = np.where(sel, 1, 0)
    X[..., 1] = np.where(sel, 0, 1)
    e1 = _cross(v, X)
    e1 = e1 / np.sqrt(dot3(e1, e1))[..., None]
    return e1, _cross(v, e1)


def _cross(a: NDArray, b: NDArray) -> NDArray:
    """GLSL ``cross`` in its operation order."""
    return np.stack([a[..., 1] * b[..., 2] - b[..., 1] * a[..., 2], a[..., 2] * b[..., 0] - b[..., 2] * a[..., 0],
                     a[..., 0] * b[..., 1] - b[..., 0] * a[..., 1]], axis=-1)
