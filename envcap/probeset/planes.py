"""The three planes of the parallax model, and their fit from a probe's captured distances.

Every probe (and every street) of a probe set carries three planes in absolute world
coordinates (meters): the two facade coordinates on the street's cross axis and the ground
height.  They come from the scene's street description (*nominal*, :class:`Planes`) and can
also be fitted from the probe's own distance channel (:func:`fit_planes` ->
:class:`FittedPlanes`), which is what an imported mesh needs.  These dataclasses are also the
manifest's plane entries (:mod:`envcap.probeset.manifest`); their field order is the JSON key
order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube

_OMIT = {"json": "omit_none"}
"""Field metadata: the JSON key is absent when the value is ``None`` (:mod:`envcap.probeset.json_codec`)."""


@dataclass(frozen=True)
class Planes:
    """The three planes of the parallax model, in absolute world coordinates (meters).

    ``facade_min`` < ``facade_max`` are coordinates on the street's cross axis (x for a street
    along z, z for a street along x); ``ground`` is a height (y).  The manifest check
    (:func:`envcap.probeset.manifest.check_manifest`) enforces ``facade_min < facade_max``, not the
    constructor, so that a merge of fitted planes (:meth:`FittedPlanes.merged`) can be built and
    then rejected by its user.
    """

    facade_min: float
    facade_max: float
    ground: float
    ground_slope: float | None = field(default=None, metadata=_OMIT)
    """Rise of the ground (m per m) along the street's +along axis (frame x for a framed street,
    the world axis otherwise): ``y_ground(s) = ground + ground_slope * (s - s_probe)``, through
    ``ground`` at the probe's along coordinate.  ``None`` (omitted from the JSON) or 0: horizontal."""

    @property
    def slope(self) -> float:
        """``ground_slope`` as a number (0.0 when ``None``)."""
        return 0.0 if self.ground_slope is None else float(self.ground_slope)

    def as_array(self) -> NDArray[np.float64]:
        """``(3,)`` float64 ``[facade_min, facade_max, ground]`` (m): the order of the GLSL
        uniforms and of :class:`envcap.runtime.street.RuntimeStreet` planes."""
        return np.array([self.facade_min, self.facade_max, self.ground], dtype=np.float64)


@dataclass(frozen=True)
class PerPlane:
    """One number per plane (the unit is that of the field holding it: sr, m)."""

    facade_min: float
    facade_max: float
    ground: float


@dataclass(frozen=True)
class FittedPlanes:
    """Planes fitted from a probe's distance channel (meters, as :class:`Planes`).

    A plane that the capture does not see well enough (its supporting texels cover less than
    ``min_coverage_sr`` steradians) is ``None``: the caller falls back to the nominal plane.
    ``coverage_sr``: per plane, the solid angle (sr) of the texels that support it;
    ``spread_m``: the robust spread (m, median absolute deviation) of their coordinates (0 when
    the plane was not fitted); both rounded to 1e-6.
    """

    facade_min: float | None
    facade_max: float | None
    ground: float | None
    coverage_sr: PerPlane
    spread_m: PerPlane
    ground_slope: float | None = field(default=None, metadata=_OMIT)
    """Fitted rise of the ground along the street (m per m, as :attr:`Planes.ground_slope`), or
    ``None`` (omitted from the JSON) where the ground texels do not support a slope."""

    def merged(self, nominal: Planes) -> Planes:
        """These planes where fitted, the ``nominal`` ones elsewhere (order not checked); the
        ground slope likewise (the fitted one, else the nominal one)."""
        return Planes(
            nominal.facade_min if self.facade_min is None else self.facade_min,
            nominal.facade_max if self.facade_max is None else self.facade_max,
            nominal.ground if self.ground is None else self.ground,
            nominal.ground_slope if self.ground_slope is None else self.ground_slope,
        )


def _robust_mode(
    values: NDArray[np.float64], weights: NDArray[np.float64], bin_m: float, near: float, min_weight: float
) -> tuple[float | None, float]:
    """The plane among ``values`` (hit coordinates, with solid-angle ``weights``).

    Histogram with ``bin_m`` bins, smoothed over 3 bins; every local maximum that holds at least
    ``min_weight`` and a quarter of the highest peak is a candidate plane, and the candidate
    closest to ``near`` (the probe) wins: the street front, not a wall seen through a gap.  The
    estimate is refined by the weighted median of the values within 2 bins of the peak.
    Returns (estimate, median absolute deviation), or ``(None, nan)`` when no bin holds
    ``min_weight`` (votes spread thin over many distances: a sparse mesh, or a street placed
    away from its buildings).
    """
    lo, hi = float(values.min()), float(values.max())
    nb = max(1, int(math.ceil((hi - lo) / bin_m)) + 1)
    idx = np.minimum(((values - lo) / bin_m).astype(np.int64), nb - 1)
    hist = np.bincount(idx, weights=weights, minlength=nb)
    smooth = hist.copy()
    smooth[1:] += hist[:-1]
    smooth[:-1] += hist[1:]
    padded = np.concatenate([[-1.0], smooth, [-1.0]])
    is_max = (smooth >= padded[:-2]) & (smooth >= padded[2:])
    good = is_max & (smooth >= max(min_weight, 0.25 * smooth.max()))
    cand = np.flatnonzero(good)
    if cand.size == 0:
        return None, float("nan")
    centers = lo + (cand + 0.5) * bin_m
    peak = float(centers[np.argmin(np.abs(centers - near))])
    sel = np.abs(values - peak) <= 2 * bin_m
    v, w = values[sel], weights[sel]
    order = np.argsort(v)
    cw = np.cumsum(w[order])
    med = float(v[order][np.searchsorted(cw, 0.5 * cw[-1])])
    mad = float(np.median(np.abs(v - med)))
    return med, mad


@lru_cache(maxsize=4)
def _texel_geometry(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Texel directions ``(6, n, n, 3)`` and solid angles ``(6, n, n)``, read-only, kept for the
    next probe (a bake fits every probe at one size: 0.03 s each at 256^2 otherwise)."""
    dirs, omega = cube.texel_directions(n), cube.texel_solid_angles(n)
    dirs.setflags(write=False)
    omega.setflags(write=False)
    return dirs, omega


def fit_planes(
    position: NDArray[np.floating] | tuple[float, float, float],
    distance: NDArray[np.floating],
    alpha: NDArray[np.floating],
    axis: str,
    *,
    min_coverage_sr: float = 0.05,
    bin_m: float = 0.05,
    max_distance: float = 500.0,
    fit_slope: bool = False,
) -> FittedPlanes:
    """Fit the two facade planes and the ground plane from one probe's distance channel.

    ``position`` (3,) is the probe center (m); ``distance`` (6, N, N) the radial distance (m) and
    ``alpha`` (6, N, N) the coverage (geometry where > 0.5) of its capture, in the conventions of
    :mod:`envcap.core.cube`; ``axis`` is the street axis ("x" or "z").

    Method (robust to windows, gaps between buildings, cars and ragged setbacks): every covered
    texel gives a hit point ``p + d * distance``.  Texels looking down (d_y < -0.5) vote for the
    ground with their hit height; texels looking sideways towards either facade
    (|d_cross| > 0.5 and |d_y| < 0.7) vote for that facade with their hit cross coordinate.  Each
    vote is weighted by its texel's solid angle.  The votes' histogram (``bin_m`` bins) has a
    peak per plane-like surface; of the substantial peaks, the one nearest the probe is the plane
    (the street front rather than a wall seen through a gap), refined by the weighted median
    near it.  Peaks, not means, are what make it robust: rays through a gap, onto a set-back
    building or onto windows only add votes elsewhere.  A facade must lie on its own side of the probe.
    A plane whose votes cover ``min_coverage_sr`` but form no peak of a quarter of that is not
    fitted (``None``, its coverage recorded): :func:`unfitted_but_seen` names it.

    ``fit_slope`` (sloped terrain): the ground is also fitted as a line ``y = g + k (s - s_p)``
    against the along coordinate ``s`` (axis ``axis`` of ``position``'s frame) by
    :func:`fit_ground_line`; where it holds, ``ground = g`` and ``ground_slope = k`` (spread: the
    residuals' MAD), and the facade votes leave out hits on that sloped ground.  Without it (the
    default) the outputs are those of a horizontal ground, ``ground_slope`` ``None``.
    """
    if axis not in ("x", "z"):
        raise ValueError(f"street axis must be 'x' or 'z', got {axis!r}")
    distance = cube.check_cube(np.asarray(distance, dtype=np.float64)[..., None], "distance")[..., 0]
    alpha = np.asarray(alpha, dtype=np.float64)
    if alpha.shape != distance.shape:
        raise ValueError(f"alpha shape {alpha.shape} differs from distance shape {distance.shape}")
    p = np.asarray(position, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"probe position must be 3 finite numbers, got {position!r}")
    n = distance.shape[1]
    dirs, omega = _texel_geometry(n)
    ok = (alpha > 0.5) & np.isfinite(distance) & (distance > 0) & (distance < max_distance)
    hits = p + dirs * np.where(ok, distance, 0.0)[..., None]
    ci = 2 if axis == "x" else 0
    dy = dirs[..., 1]
    dc = dirs[..., ci]

    def fit(mask: NDArray[np.bool_], coord: NDArray[np.float64], near: float) -> tuple[float | None, float, float]:
        m = mask & ok
        cov = float(omega[m].sum())
        if cov < min_coverage_sr or not np.any(m):
            return None, cov, float("nan")
        est, mad = _robust_mode(coord[m], omega[m], bin_m, near, 0.25 * min_coverage_sr)
        return est, cov, mad

    ground, cg, sg = fit(dy < -0.5, hits[..., 1], p[1])
    slope = None
    ai = 2 - ci
    down = (dy < -0.5) & ok
    if fit_slope and cg >= min_coverage_sr:
        line = fit_ground_line(hits[..., ai][down] - p[ai], hits[..., 1][down], omega[down], ground, bin_m)
        if line is not None:
            ground, slope, sg = line
    # Facade votes: sideways texels whose hit is not on the ground (those only spread along the
    # cross axis and would bias the mode).
    gy = ground if ground is not None else float(np.min(np.where(ok, hits[..., 1], np.inf), initial=p[1]))
    if slope is not None:
        gy = gy + slope * (hits[..., ai] - p[ai])
    off_ground = hits[..., 1] > gy + max(0.1, 4 * bin_m)
    sideways = (np.abs(dy) < 0.7) & off_ground
    fmax, cmax, smax = fit((dc > 0.5) & sideways, hits[..., ci], p[ci])
    fmin, cmin, smin = fit((dc < -0.5) & sideways, hits[..., ci], p[ci])
    if fmax is not None and fmax <= p[ci]:
        fmax = None
    if fmin is not None and fmin >= p[ci]:
        fmin = None
    if ground is not None and ground >= p[1]:
        ground = None
    coverage = PerPlane(round(cmin, 6), round(cmax, 6), round(cg, 6))
    spread = PerPlane(*(round(v if math.isfinite(v) else 0.0, 6) for v in (smin, smax, sg)))
    return FittedPlanes(fmin, fmax, ground, coverage, spread, slope)


SLOPE_SPAN_MIN_M = 0.5
"""A ground line needs its votes' along coordinates to spread (weighted standard deviation) at
least this far (m): a probe seeing only a sliver of ground says nothing of its slope."""
SLOPE_MAX = 1.0
"""Ground slopes steeper than this (45 deg) are not streets: no slope is fitted."""
SLOPE_INLIERS_MIN = 0.5
"""Share (by solid angle) of the ground votes the fitted line must hold (Tukey weight > 0)."""


def fit_ground_line(ds: NDArray[np.float64], y: NDArray[np.float64], w: NDArray[np.float64],
                    start: float | None, bin_m: float = 0.05, iterations: int = 30) -> tuple[float, float, float] | None:
    """Robust line ``y = g + k ds`` through ground votes: ``ds`` (K,) m along the street from the
    probe, ``y`` (K,) hit heights (m), ``w`` (K,) solid-angle weights (sr).

    Iteratively reweighted least squares with Tukey's biweight (c = 4.685 robust sigmas, the
    sigma at least ``bin_m``), starting horizontal at ``start`` (the ground's histogram mode;
    the weighted median of ``y`` when ``None``).  Returns ``(g, k, MAD of the inliers'
    residuals)`` (m, m per m, m; the MAD rounded to 1e-6), or ``None`` when the votes do not
    support a slope: their along spread is below :data:`SLOPE_SPAN_MIN_M`, the line holds less
    than :data:`SLOPE_INLIERS_MIN` of them, ``|k| >`` :data:`SLOPE_MAX`, or the fit is not finite.
    """
    if ds.size < 3 or not w.sum() > 0:
        return None
    mean = float(np.average(ds, weights=w))
    if math.sqrt(float(np.average((ds - mean) ** 2, weights=w))) < SLOPE_SPAN_MIN_M:
        return None
    if start is None:
        order = np.argsort(y)
        start = float(y[order][np.searchsorted(np.cumsum(w[order]), 0.5 * w.sum())])
    g, k = float(start), 0.0
    tw = w
    for _ in range(iterations):
        r = y - (g + k * ds)
        sigma = max(1.4826 * float(np.median(np.abs(r[tw > 0]))), bin_m)
        u = r / (4.685 * sigma)
        tw = w * np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)
        a = np.array([[tw.sum(), (tw * ds).sum()], [(tw * ds).sum(), (tw * ds * ds).sum()]])
        if not abs(np.linalg.det(a)) > 1e-12 * max(1.0, float(a[0, 0] * a[1, 1])):
            return None
        g_new, k_new = np.linalg.solve(a, [(tw * y).sum(), (tw * ds * y).sum()])
        done = abs(g_new - g) < 1e-9 and abs(k_new - k) < 1e-12
        g, k = float(g_new), float(k_new)
        if done:
            break
    inl = tw > 0
    if not (math.isfinite(g) and math.isfinite(k) and abs(k) <= SLOPE_MAX and w[inl].sum() >= SLOPE_INLIERS_MIN * w.sum()):
        return None
    return g, k + 0.0, round(float(np.median(np.abs(y[inl] - g - k * ds[inl]))), 6)


PLANE_NAMES = ("facade_min", "facade_max", "ground")
"""The three planes, in :class:`Planes` field order."""


def unfitted_but_seen(fitted: FittedPlanes, min_coverage_sr: float = 0.05) -> tuple[str, ...]:
    """The planes (names of :data:`PLANE_NAMES`) that ``fitted`` leaves to the nominal ones although
    their side was covered (at least ``min_coverage_sr`` sr of votes, the default of
    :func:`fit_planes`): geometry was seen there but no plane stood out (sparse or misplaced
    geometry), as opposed to open sky or an empty side."""
    cov = fitted.coverage_sr
    return tuple(name for name in PLANE_NAMES
                 if getattr(fitted, name) is None and getattr(cov, name) >= min_coverage_sr)
