"""Crossings: where streets meet, the region they share and the probe at its centre.

Plan geometry only (world meters, plan points ``(x, z)``).  A street's **corridor** is its closed
rectangle between its ends and its facades, in its frame (``start <= along <= end``,
``facade_min <= across <= facade_max``; the street map's rule, :mod:`envcap.runtime.street_map`).
Its **centre line** is the probe line (``across = center``) over ``[start, end]``.

Two streets **meet** where their centre lines, extended without end, intersect at a point ``c``
that lies inside both corridors (closed, :data:`TOL` m of slack for the intersection's rounding):
an X crossing, and a T-junction whose side street runs on into the main street's roadway as far as
its centre line.  Parallel streets never meet (not even overlapping ones); a side street that stops
at the other street's facade (corridors touching along an edge only) does not meet it: its centre
line ends before the other's.  Meetings whose centres lie within :data:`MERGE_M` of each other are
one crossing of all their streets (three or more streets through one point).

The **crossing region** is where the corridors of at least two of the crossing's streets overlap
(for two streets: the intersection of their corridors, a parallelogram).  A point inside several
crossings' regions belongs to the crossing whose centre is nearest (ties: the lower index).

Works on scene streets (:class:`envcap.scene.model.Street`: ``facade_min``, ``facade_max``,
``center_line``) and on a manifest's streets (:class:`envcap.probeset.manifest.Street`: ``planes``,
``center``) alike (:func:`corridor`).  The crossing probe: :func:`crossing_alongs` (where a bake puts
it on the first meeting street), :class:`envcap.probeset.crossing_table.Crossing` (the manifest's
record).  ``docs/crossings.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.street_frame import frame_to_world, world_to_frame

TOL = 1e-6
"""Slack (m) of the 'centre inside both corridors' test: the intersection is computed in float64."""

MERGE_M = 0.01
"""Meetings whose centres are closer than this (m) are one crossing."""


@dataclass(frozen=True)
class Corridor:
    """One street's corridor and centre line in its frame: ``along`` / ``cross`` axis indices,
    ``start`` < ``end`` (m, along), facades ``fmin`` < ``fmax`` and ``center`` (m, across), the
    frame ``yaw_deg`` / ``origin_xz``."""

    name: str
    along: int
    cross: int
    start: float
    end: float
    fmin: float
    fmax: float
    center: float
    yaw_deg: float = 0.0
    origin_xz: tuple[float, float] = (0.0, 0.0)

    def frame_of(self, xz: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(along, across)`` (m, float64) of world plan points ``xz`` ``(..., 2)``."""
        p = np.asarray(xz, np.float64)
        f = world_to_frame(np.stack([p[..., 0], np.zeros_like(p[..., 0]), p[..., 1]], axis=-1),
                           self.yaw_deg, self.origin_xz)
        return f[..., self.along], f[..., self.cross]

    def contains(self, xz: ArrayLike, tol: float = 0.0) -> NDArray[np.bool_]:
        """Whether world plan points ``xz`` ``(..., 2)`` lie in the closed corridor (``tol`` m of
        slack); NaN points never do."""
        a, c = self.frame_of(xz)
        with np.errstate(invalid="ignore"):
            return ((a >= self.start - tol) & (a <= self.end + tol) & (c >= self.fmin - tol) & (c <= self.fmax + tol))

    def point(self, along: float) -> NDArray[np.float64]:
        """The world plan point ``(2,)`` of the centre line at ``along`` (m)."""
        f = np.zeros(3)
        f[self.along], f[self.cross] = along, self.center
        return frame_to_world(f, self.yaw_deg, self.origin_xz)[[0, 2]]


def corridor(street: Any) -> Corridor:
    """The :class:`Corridor` of a scene street or a manifest street (module docstring)."""
    if hasattr(street, "planes"):
        fmin, fmax, center = street.planes.facade_min, street.planes.facade_max, street.center
    else:
        fmin, fmax, center = street.facade_min, street.facade_max, street.center_line
    yaw = getattr(street, "yaw_deg", None)
    oxz = getattr(street, "origin_xz", None)
    return Corridor(str(street.name), int(street.along_index), int(street.cross_index), float(street.start),
                    float(street.end), float(fmin), float(fmax), float(center),
                    0.0 if yaw is None else float(yaw), (0.0, 0.0) if oxz is None else (float(oxz[0]), float(oxz[1])))


@dataclass(frozen=True)
class Meeting:
    """A crossing found in plan: ``centre`` (x, z) m and the indices of its streets (ascending, >= 2)."""

    centre: tuple[float, float]
    streets: tuple[int, ...]


def _meet(a: Corridor, b: Corridor) -> NDArray[np.float64] | None:
    """The plan point where the centre lines of ``a`` and ``b`` intersect, when it lies in both corridors."""
    pa, pb = a.point(0.0), b.point(0.0)
    ua, ub = a.point(1.0) - pa, b.point(1.0) - pb
    det = ua[0] * ub[1] - ua[1] * ub[0]              # unit directions: |det| = |sin(angle)|
    if abs(det) < 1e-9:
        return None                                  # parallel (or the same line): they never cross
    d = pb - pa
    t = (d[0] * ub[1] - d[1] * ub[0]) / det
    c = pa + t * ua
    if not (np.all(np.isfinite(c)) and a.contains(c, TOL) and b.contains(c, TOL)):
        return None
    return c


def detect_crossings(streets: Sequence[Any]) -> list[Meeting]:
    """The crossings of ``streets`` (scene or manifest streets, module docstring), in the order of
    their first pair ``(i, j)``, ``i < j``."""
    cors = [corridor(s) for s in streets]
    found: list[tuple[NDArray[np.float64], set[int]]] = []
    for i in range(len(cors)):
        for j in range(i + 1, len(cors)):
            c = _meet(cors[i], cors[j])
            if c is None:
                continue
            for centre, members in found:
                if math.hypot(*(centre - c)) < MERGE_M:
                    members.update((i, j))
                    break
            else:
                found.append((c, {i, j}))
    return [Meeting((float(c[0]), float(c[1])), tuple(sorted(m))) for c, m in found]


def crossing_of(corridors: Sequence[Corridor], meetings: Sequence[Meeting], xz: ArrayLike) -> NDArray[np.int64]:
    """Per world plan point ``xz`` ``(..., 2)``: the index of the crossing whose region holds it
    (-1: none; overlapping regions: the nearest centre, ties the lower index).  ``corridors``: of
    all the streets the meetings' indices refer to."""
    p = np.asarray(xz, np.float64)
    out = np.full(p.shape[:-1], -1, np.int64)
    best = np.full(p.shape[:-1], np.inf)
    for k, m in enumerate(meetings):
        n_in = sum(corridors[i].contains(p).astype(np.int64) for i in m.streets)
        dist = np.hypot(p[..., 0] - m.centre[0], p[..., 1] - m.centre[1])
        take = (n_in >= 2) & (dist < best)
        out[take], best[take] = k, dist[take]
    return out


def crossing_alongs(corridors: Sequence[Corridor], meetings: Sequence[Meeting]) -> dict[int, list[float]]:
    """Where a bake puts the crossing probes: per street index, the along coordinates (m, its frame)
    of the centres of the crossings it owns (a crossing's owner: its first street)."""
    out: dict[int, list[float]] = {}
    for m in meetings:
        owner = corridors[m.streets[0]]
        out.setdefault(m.streets[0], []).append(float(owner.frame_of(np.array(m.centre))[0]))
    return out


def meetings_of(streets: Sequence[Any], table: Sequence[Any] | None) -> list[Meeting]:
    """The :class:`Meeting` of each entry of a manifest's ``crossings`` table (``None``: none):
    its centre's plan point and the indices of its streets in ``streets`` (the manifest's)."""
    index = {str(st.name): i for i, st in enumerate(streets)}
    return [Meeting((float(c.centre[0]), float(c.centre[2])), tuple(index[n] for n in c.streets)) for c in table or ()]
