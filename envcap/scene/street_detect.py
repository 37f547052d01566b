"""Find straight streets in a city mesh from its building facades (``envcap streets``).

A street is the free strip between two facade lines that face each other.  The method, in the
world frame (meters, +Y up; plan angles ``atan2(dz, dx)`` in degrees):

1. **Walls**: triangles whose normal is within ``wall_tilt_deg`` of horizontal; each has a plan
   normal angle and an area.  Meshes must be wound outward (import with ``winding = "auto"``).
2. **Directions**: a histogram of wall normal angles modulo 90 deg (a box building's four walls
   fall in one bin), area-weighted, 0.25 deg bins smoothed over +-0.5 deg; every peak holding
   ``min_direction_share`` of the wall area is refined by the area-weighted mean of the angles
   within +-1 deg.  Each peak a gives two street directions, a and a + 90 (mod 180).
3. **Facade lines**: for a direction (along ``t``, across ``n = (-t_z, t_x)``), the walls facing
   +n or -n within ``parallel_tol_deg``, grouped by facing and by offset ``v = p . n`` (0.3 m
   tolerance) into lines: offset (area-weighted), the union of their ``u = p . t`` intervals,
   their heights.
4. **Pairs**: at samples every ``sample_m`` along u, each +n-facing facade at v = a is paired with
   the nearest -n-facing facade covering the same sample at v = b > a: the strip between is
   free of those facades by construction.  Pairs ``min_width`` <= b - a <= ``max_width`` are
   clustered by centre line (``centre_tol_m``); a cluster's samples, bridged over gaps up to
   ``max_gap_m`` (crossings, gaps between buildings), give the street's extent; its facade
   offsets are the medians of a and b; clusters shorter than ``min_length`` are dropped.
5. **Intersections**: two streets whose centre lines cross within both extents meet there; each
   street records the crossing distances and the intersections their centre points.

Frontage share: the fraction of the extent where that side's facade is present.  Heights: per
side, the median over 1 m samples along the paired facade lines of the wall height there (m).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import NDArray

Tick = Callable[[str], None]
"""A progress callback: one short text of how far a search got."""


class NoWalls(ValueError):
    """:func:`detect_streets` found no near-vertical triangle: nothing to find streets between
    (often a mesh read with the wrong up axis)."""


@dataclass(frozen=True)
class StreetSearch:
    """Parameters of :func:`detect_streets` (meters, degrees); see the module docstring."""

    wall_tilt_deg: float = 10.0
    min_direction_share: float = 0.01
    parallel_tol_deg: float = 1.0
    sample_m: float = 1.0
    min_width: float = 5.0
    max_width: float = 80.0
    centre_tol_m: float = 2.0
    max_gap_m: float = 25.0
    min_length: float = 30.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"StreetSearch.{name} must be a positive number, got {value!r}")
        if self.max_width <= self.min_width:
            raise ValueError("StreetSearch.max_width must exceed min_width")


@dataclass(frozen=True)
class DetectedStreet:
    """One straight street found by :func:`detect_streets`.

    ``p0``/``p1``: plan end points (x, z) of its centre line (m); ``angle_deg``: direction p0 ->
    p1 in [0, 180); ``facade_offsets``: signed offsets (m) of its two facade lines from the centre
    line along the plan normal ``(-sin a, cos a)`` (first negative); ``frontage``: share of the
    extent with a facade on each side; ``heights``: median building height on each side (m);
    ``crossings``: distances from p0 (m) where other streets' centre lines cross it;
    ``segments``: the street split at its crossings, ``(start, end)`` distances from p0 (m) of
    each stretch between the crossing streets' facades (the whole street when it crosses none)."""

    name: str
    p0: tuple[float, float]
    p1: tuple[float, float]
    angle_deg: float
    facade_offsets: tuple[float, float]
    frontage: tuple[float, float]
    heights: tuple[float, float]
    crossings: tuple[float, ...]
    segments: tuple[tuple[float, float], ...] = ()

    @property
    def width(self) -> float:
        """Facade to facade (m)."""
        return self.facade_offsets[1] - self.facade_offsets[0]

    @property
    def length(self) -> float:
        """Centre-line length in plan (m)."""
        return float(np.hypot(self.p1[0] - self.p0[0], self.p1[1] - self.p0[1]))


@dataclass(frozen=True)
class FacadeLine:
    """Walls of one facing at one offset: ``facing`` +1 (normal +n) or -1; ``offset`` v (m);
    ``intervals`` (K, 2) merged u ranges (m); ``height`` median wall height (m)."""

    facing: int
    offset: float
    intervals: NDArray[np.float64]
    height: float


def wall_triangles(triangles: NDArray[np.float64], tilt_deg: float = 10.0) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The near-vertical triangles of ``triangles`` (T, 3, 3) (world m): their vertices (W, 3, 3),
    plan normal angles (W,) in degrees (``atan2(n_z, n_x)``) and areas (W,) in m^2."""
    tri = np.asarray(triangles, dtype=np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3) or not np.all(np.isfinite(tri)):
        raise ValueError(f"triangles must be a finite (T, 3, 3) array, got shape {tri.shape}")
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1)
    keep = (length > 1e-9) & (np.abs(normal[:, 1]) <= np.sin(np.radians(tilt_deg)) * np.maximum(length, 1e-300))
    normal = normal[keep]
    return tri[keep], np.degrees(np.arctan2(normal[:, 2], normal[:, 0])), 0.5 * length[keep]


def street_directions(angles_deg: NDArray[np.float64], areas: NDArray[np.float64], min_share: float = 0.01) -> list[float]:
    """Dominant wall directions modulo 90 deg (see step 2), each in [0, 90), strongest first."""
    folded = np.mod(angles_deg, 90.0)
    bins = np.bincount(np.floor(folded / 0.25).astype(int) % 360, weights=areas, minlength=360)
    smooth = bins + np.roll(bins, 1) + np.roll(bins, -1) + 0.5 * (np.roll(bins, 2) + np.roll(bins, -2))
    order = np.argsort(-smooth)
    peaks: list[float] = []
    total = float(areas.sum())
    for b in order:
        if smooth[b] < min_share * total * 3.0:
            break
        centre = (b + 0.5) * 0.25
        if any(abs((centre - p + 45.0) % 90.0 - 45.0) < 2.0 for p in peaks):
            continue
        d = (folded - centre + 45.0) % 90.0 - 45.0
        near = np.abs(d) < 1.0
        peaks.append(float((centre + np.average(d[near], weights=areas[near])) % 90.0))
    return peaks


def _merge(intervals: NDArray[np.float64], gap: float) -> NDArray[np.float64]:
    iv = intervals[np.argsort(intervals[:, 0])]
    out = [iv[0].copy()]
    for lo, hi in iv[1:]:
        if lo <= out[-1][1] + gap:
            out[-1][1] = max(out[-1][1], hi)
        else:
            out.append(np.array([lo, hi]))
    return np.array(out)


def facade_lines(walls: NDArray[np.float64], angles_deg: NDArray[np.float64], areas: NDArray[np.float64],
                 direction_deg: float, tol_deg: float = 1.0, progress: Tick | None = None) -> list[FacadeLine]:
    """Facade lines of the walls parallel to ``direction_deg`` (see step 3); ``progress(text)``
    after each line."""
    a = np.radians(direction_deg)
    t = np.array([np.cos(a), np.sin(a)])
    n = np.array([-t[1], t[0]])
    normal_deg = direction_deg + 90.0
    lines: list[FacadeLine] = []
    for facing, target in ((1, normal_deg), (-1, normal_deg + 180.0)):
        sel = np.abs((angles_deg - target + 180.0) % 360.0 - 180.0) < tol_deg
        if not sel.any():
            continue
        plan = walls[sel][:, :, [0, 2]]
        v = (plan @ n).mean(axis=1)
        u = plan @ t
        heights = walls[sel][:, :, 1]
        w = areas[sel]
        order = np.argsort(v)
        groups = np.split(order, np.nonzero(np.diff(v[order]) > 0.3)[0] + 1)
        for k, g in enumerate(groups):
            if progress is not None:
                progress(f"facade line {k + 1} of {len(groups)}")
            u_lo, u_hi = u[g].min(axis=1), u[g].max(axis=1)
            iv = _merge(np.stack([u_lo, u_hi], axis=1), 0.05)
            lines.append(FacadeLine(facing, float(np.average(v[g], weights=w[g])), iv,
                                    _median_height(u_lo, u_hi, heights[g].min(axis=1), heights[g].max(axis=1))))
    return lines


def _median_height(u_lo: NDArray[np.float64], u_hi: NDArray[np.float64], y_lo: NDArray[np.float64],
                   y_hi: NDArray[np.float64], step: float = 1.0) -> float:
    """Median over samples every ``step`` m along a facade line of the wall height there (top of
    the walls covering the sample minus their bottom): one building's height per stretch of it,
    not the whole line's range (which a slope or a tall neighbour would inflate)."""
    samples = np.arange(u_lo.min(), u_hi.max(), step) + 0.5 * step
    cover = (samples[:, None] >= u_lo[None, :]) & (samples[:, None] <= u_hi[None, :])
    seen = cover.any(axis=1)
    if not seen.any():
        return float(y_hi.max() - y_lo.min())
    top = np.where(cover, y_hi[None, :], -np.inf).max(axis=1)[seen]
    bottom = np.where(cover, y_lo[None, :], np.inf).min(axis=1)[seen]
    return float(np.median(top - bottom))


def _covers(line: FacadeLine, u: NDArray[np.float64]) -> NDArray[np.bool_]:
    iv = line.intervals
    return np.any((u[:, None] >= iv[None, :, 0]) & (u[:, None] <= iv[None, :, 1]), axis=1)


def _runs(samples: NDArray[np.float64], gap: float) -> list[tuple[float, float]]:
    s = np.sort(samples)
    cuts = np.nonzero(np.diff(s) > gap)[0]
    starts = np.r_[0, cuts + 1]
    ends = np.r_[cuts, len(s) - 1]
    return [(float(s[i]), float(s[j])) for i, j in zip(starts, ends)]


def _streets_along(lines: list[FacadeLine], walls_uv: NDArray[np.float64], search: StreetSearch,
                   progress: Tick | None = None) -> list[tuple[float, float, float, float, float, float, float, float]]:
    """(u0, u1, v_a, v_b, frontage_a, frontage_b, height_a, height_b) per street along one direction;
    ``walls_uv`` (W, 4): every wall's u and v ranges in that direction's frame (see :func:`_extend`)."""
    plus = [ln for ln in lines if ln.facing == 1]
    minus = [ln for ln in lines if ln.facing == -1]
    if not plus or not minus:
        return []
    lo = min(float(ln.intervals[:, 0].min()) for ln in lines)
    hi = max(float(ln.intervals[:, 1].max()) for ln in lines)
    u = np.arange(lo, hi + search.sample_m, search.sample_m)
    ordered = sorted(lines, key=lambda ln: ln.offset)
    cover = np.array([_covers(ln, u) for ln in ordered])                # (L, S)
    offsets = np.array([ln.offset for ln in ordered])
    facing = np.array([ln.facing for ln in ordered])
    minus_index = {id(ln): k for k, ln in enumerate(minus)}
    plus_index = {id(ln): k for k, ln in enumerate(plus)}
    pairs: list[tuple[float, int, int]] = []                            # (u, plus idx, minus idx)
    for k, ln in enumerate(plus):
        if progress is not None:
            progress(f"pairing facade {k + 1} of {len(plus)}")
        cov = _covers(ln, u)
        if not cov.any():
            continue
        # a wall facing back at the same offset: buildings back to back, no street here
        back = ((facing == -1) & (np.abs(offsets - ln.offset) < 0.3))[:, None] & cover[:, cov]
        ahead = (offsets > ln.offset + 0.3)[:, None] & cover[:, cov]    # the first wall in front, any facing
        first = np.where(ahead.any(axis=0), np.argmax(ahead, axis=0), -1)
        for s, j, blocked in zip(u[cov], first, back.any(axis=0)):
            if blocked or j < 0 or facing[j] != -1:
                continue
            if search.min_width <= offsets[j] - ln.offset <= search.max_width:
                pairs.append((float(s), plus_index[id(ln)], minus_index[id(ordered[j])]))
    if not pairs:
        return []
    arr = np.array(pairs)
    centre = np.array([(plus[int(i)].offset + minus[int(j)].offset) / 2.0 for _, i, j in pairs])
    order = np.argsort(centre)
    clusters = np.split(order, np.nonzero(np.diff(centre[order]) > search.centre_tol_m)[0] + 1)
    found = []
    for k, c in enumerate(clusters):
        if progress is not None:
            progress(f"centre line {k + 1} of {len(clusters)}")
        runs = []                                                       # (ext. start, ext. end, u0, u1)
        for u0, u1 in _runs(arr[c, 0], search.max_gap_m):
            if u1 - u0 < search.min_length:
                continue
            inside = c[(arr[c, 0] >= u0) & (arr[c, 0] <= u1)]
            va = float(np.median([plus[int(k)].offset for k in arr[inside, 1]]))
            vb = float(np.median([minus[int(k)].offset for k in arr[inside, 2]]))
            covered = np.any([_covers(ln, u) for ln in plus if abs(ln.offset - va) < 0.3]
                             + [_covers(ln, u) for ln in minus if abs(ln.offset - vb) < 0.3]
                             + [np.zeros(u.size, bool)], axis=0)
            runs.append((*_extend(u, covered, _blocked(walls_uv, va, vb, u), u0, u1, search.max_gap_m), u0, u1))
        runs.sort()
        groups: list[list[tuple[float, float, float, float]]] = []
        for run in runs:                                                # extended runs that overlap: one street
            if groups and run[0] <= max(r[1] for r in groups[-1]):
                groups[-1].append(run)
            else:
                groups.append([run])
        for group in groups:
            e0, e1 = min(r[0] for r in group), max(r[1] for r in group)
            keep = np.any([(arr[c, 0] >= r[2]) & (arr[c, 0] <= r[3]) for r in group], axis=0)
            inside = c[keep]
            pi, mi = arr[inside, 1].astype(int), arr[inside, 2].astype(int)
            va = float(np.median([plus[k].offset for k in pi]))
            vb = float(np.median([minus[k].offset for k in mi]))
            span = np.arange(e0, e1 + search.sample_m / 2, search.sample_m)
            paired_a, paired_b = set(pi.tolist()), set(mi.tolist())
            side_a = np.any([_covers(ln, span) for k, ln in enumerate(plus) if k in paired_a or abs(ln.offset - va) < 0.3],
                            axis=0)
            side_b = np.any([_covers(ln, span) for k, ln in enumerate(minus) if k in paired_b or abs(ln.offset - vb) < 0.3],
                            axis=0)
            ha = float(np.median([plus[k].height for k in pi]))
            hb = float(np.median([minus[k].height for k in mi]))
            found.append((e0, e1, va, vb, float(side_a.mean()), float(side_b.mean()), ha, hb))
    return found


def _blocked(walls_uv: NDArray[np.float64], va: float, vb: float, u: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Samples ``u`` where a wall of any direction stands in the strip between the facade lines at
    ``va`` < ``vb`` (more than 0.3 m from both); ``walls_uv`` (W, 4): each wall's u and v ranges."""
    inside = (walls_uv[:, 3] > va + 0.3) & (walls_uv[:, 2] < vb - 0.3)
    if not inside.any():
        return np.zeros(u.size, bool)
    iv = _merge(walls_uv[inside][:, :2], 0.0)
    k = np.searchsorted(iv[:, 0], u, side="right") - 1
    return (k >= 0) & (u <= iv[np.maximum(k, 0), 1])


def _extend(u: NDArray[np.float64], covered: NDArray[np.bool_], blocked: NDArray[np.bool_], u0: float, u1: float,
            max_gap: float) -> tuple[float, float]:
    """A street's paired extent [u0, u1] extended at each end over the samples where one of its two
    facade lines goes on (one-sided frontage: a missing building, a plaza on one side), bridging
    gaps up to ``max_gap`` and stopping before anything that stands in the street."""
    ends = []
    for end, ahead in ((u0, u < u0), (u1, u > u1)):
        cand, cov, blk = u[ahead], covered[ahead], blocked[ahead]
        if end == u0:
            cand, cov, blk = cand[::-1], cov[::-1], blk[::-1]
        if blk.any():
            first = int(np.argmax(blk))
            cand, cov = cand[:first], cov[:first]
        pts = cand[cov]
        steps = np.abs(np.diff(np.r_[end, pts]))
        far = np.nonzero(steps > max_gap)[0]
        pts = pts[:far[0]] if far.size else pts
        ends.append(float(pts[-1]) if pts.size else end)
    return ends[0], ends[1]


def _crossing(a: DetectedStreet, b: DetectedStreet) -> float | None:
    """Distance along ``a`` from its p0 where ``b``'s centre line crosses it, if within both."""
    pa, pb = np.array(a.p0), np.array(b.p0)
    da, db = np.array(a.p1) - pa, np.array(b.p1) - pb
    den = da[0] * db[1] - da[1] * db[0]
    if abs(den) < 1e-9 * a.length * b.length:
        return None
    r = pb - pa
    s = (r[0] * db[1] - r[1] * db[0]) / den
    q = (r[0] * da[1] - r[1] * da[0]) / den
    slack_a, slack_b = b.width / 2.0 / a.length, a.width / 2.0 / b.length
    if -slack_a <= s <= 1 + slack_a and -slack_b <= q <= 1 + slack_b:
        return float(np.clip(s, 0.0, 1.0) * a.length)
    return None


def detect_streets(triangles: NDArray[np.float64], search: StreetSearch | None = None,
                   progress: Tick | None = None) -> list[DetectedStreet]:
    """Straight streets of a city mesh, ``triangles`` (T, 3, 3) world meters (see the module
    docstring), named ``street_00``... by direction then position.  ``progress(text)`` says how far
    the search got (often: rate-limit it).  Raises :class:`NoWalls` if the mesh has no wall
    at all."""
    search = search or StreetSearch()
    walls, angles, areas = wall_triangles(triangles, search.wall_tilt_deg)
    if not len(walls):
        raise NoWalls("no walls found: the mesh has no near-vertical triangles (is its up axis right?)")
    streets: list[DetectedStreet] = []
    peaks = street_directions(angles, areas, search.min_direction_share)
    for k, peak in enumerate(peaks):
        for j, direction in enumerate((peak, peak + 90.0)):
            where = f"direction {2 * k + j + 1} of {2 * len(peaks)} ({direction % 180.0:.1f} deg)"
            tick = None if progress is None else (lambda text, where=where: progress(f"{where}: {text}"))
            direction %= 180.0
            a = np.radians(direction)
            t, n = np.array([np.cos(a), np.sin(a)]), np.array([-np.sin(a), np.cos(a)])
            lines = facade_lines(walls, angles, areas, direction, search.parallel_tol_deg, tick)
            plan_u, plan_v = walls[:, :, [0, 2]] @ t, walls[:, :, [0, 2]] @ n
            walls_uv = np.stack([plan_u.min(axis=1), plan_u.max(axis=1), plan_v.min(axis=1), plan_v.max(axis=1)], axis=1)
            for u0, u1, va, vb, fa, fb, ha, hb in _streets_along(lines, walls_uv, search, tick):
                c = (va + vb) / 2.0
                p0, p1 = u0 * t + c * n, u1 * t + c * n
                streets.append(DetectedStreet("", (float(p0[0]), float(p0[1])), (float(p1[0]), float(p1[1])),
                                              float(direction), (va - c, vb - c), (fa, fb), (ha, hb), ()))
    streets.sort(key=lambda s: (round(s.angle_deg, 1), s.p0[0], s.p0[1]))
    named = [DetectedStreet(f"street_{i:02d}", s.p0, s.p1, s.angle_deg, s.facade_offsets, s.frontage, s.heights, ())
             for i, s in enumerate(streets)]
    out = []
    for s in named:
        hits = sorted((d, o.width) for o in named if o is not s and (d := _crossing(s, o)) is not None)
        cuts = [(0.0, 0.0)] + [(d - w / 2.0, d + w / 2.0) for d, w in hits] + [(s.length, s.length)]
        segments = tuple((max(a[1], 0.0), min(b[0], s.length)) for a, b in zip(cuts[:-1], cuts[1:])
                         if min(b[0], s.length) - max(a[1], 0.0) >= 1.0)
        out.append(DetectedStreet(s.name, s.p0, s.p1, s.angle_deg, s.facade_offsets, s.frontage, s.heights,
                                  tuple(d for d, _ in hits), segments))
    return out


def intersections(streets: list[DetectedStreet]) -> list[tuple[float, float]]:
    """Plan centre points (x, z) where two detected streets' centre lines cross (one per pair)."""
    points = []
    for i, a in enumerate(streets):
        for b in streets[i + 1:]:
            d = _crossing(a, b)
            if d is not None and _crossing(b, a) is not None:
                t = (np.array(a.p1) - np.array(a.p0)) / a.length
                p = np.array(a.p0) + d * t
                points.append((float(p[0]), float(p[1])))
    return points
