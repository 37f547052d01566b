"""Where the evaluator looks: sweeps of positions in the street volumes of a probe set.

Conventions: world meters, +Y up; a street runs along axis x or z of its frame (the world, or for
a street at any angle the world turned by its yaw about its plan origin,
:mod:`envcap.core.street_frame`) between two facades (cross-axis coordinates ``facade_min <
facade_max``) above its ground (tilted along the street where the probes' planes have a slope).
Positions are sampled and described (lateral, along, height) in the street's frame and handed out
in world coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.street_frame import frame_to_world, world_to_frame
from envcap.probeset.manifest import Manifest, Street


@dataclass(frozen=True)
class Sweep:
    """Where to evaluate: ``per_street`` positions on every street of the probe set.

    Along the street: jittered strata over the probes' span (half a spacing beyond the end
    probes), at least ``end_margin`` m from the street's ends; for a set whose probes a placement
    strategy chose (``Manifest.placement``) over the whole street minus ``end_margin``, so that
    every placement of a street is measured on the same positions.  Lateral: uniform within the
    facades minus ``margin`` m.  Height: uniform in ``heights`` m above the ground.  ``seed``
    fixes everything (street ``i`` uses ``seed + i``).
    """

    per_street: int = 16
    margin: float = 1.0
    end_margin: float = 2.0
    heights: tuple[float, float] = (0.3, 3.0)
    seed: int = 5

    def __post_init__(self) -> None:
        if not (isinstance(self.per_street, int) and self.per_street >= 1):
            raise ValueError(f"sweep: per_street must be a positive integer, got {self.per_street!r}")
        vals = (self.margin, self.end_margin, *self.heights)
        if not all(math.isfinite(v) for v in vals) or self.margin < 0 or self.end_margin < 0:
            raise ValueError(f"sweep: margins must be finite and >= 0, got {self.margin}, {self.end_margin}")
        if not 0 < self.heights[0] <= self.heights[1]:
            raise ValueError(f"sweep: heights must satisfy 0 < low <= high, got {self.heights}")
        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise ValueError(f"sweep: seed must be an integer >= 0, got {self.seed!r}")


DEFAULT_SWEEP = Sweep()
QUICK_SWEEP = Sweep(per_street=6)


@dataclass(frozen=True)
class EvalPosition:
    """One evaluation position: ``position`` (3,) m on street ``street``; ``lateral`` signed
    offset (m) from the street's probe line on its cross axis; ``along`` (m) distance along the
    street to the nearest probe; ``height`` (m) above the ground; ``near_crossing``: inside
    another street's roadway (the three planes of this street are wrong there); ``yaw_deg``: the
    street's frame (the truth is captured with its cube axes along it; 0: the world's)."""

    street: str
    index: int
    position: tuple[float, float, float]
    lateral: float
    along: float
    height: float
    near_crossing: bool
    yaw_deg: float = 0.0


@dataclass(frozen=True)
class StreetExtent:
    """The volume of one street of a probe set, in its frame: ``along`` / ``cross`` axis indices,
    probe coordinates ``probe_s`` (m, ascending) along it, facades ``fmin`` < ``fmax`` (m, cross
    axis), ``ground`` height, street ``start`` .. ``end`` (m, along) and the probe line ``center``
    (m, cross); ``yaw_deg`` / ``origin_xz`` its frame; ``probe_ground`` / ``probe_slope`` ``(P,)``
    each probe's ground height and slope (the ground under a point: that of the nearest probe)."""

    name: str
    along: int
    cross: int
    probe_s: NDArray[np.float64]
    fmin: float
    fmax: float
    ground: float
    start: float
    end: float
    center: float
    yaw_deg: float = 0.0
    origin_xz: tuple[float, float] = (0.0, 0.0)
    probe_ground: NDArray[np.float64] | None = None
    probe_slope: NDArray[np.float64] | None = None

    @staticmethod
    def from_manifest(street: Street) -> "StreetExtent":
        """The extent of a manifest street (its nominal planes, extent, center line and probes)."""
        if not street.probes:
            raise ValueError(f"street {street.name!r} has no probes")
        along = street.along_index
        probes = street.probes_along()
        yaw, oxz = street.frame_yaw_deg, street.frame_origin_xz
        s = street.frame_positions(probes)[:, along]
        pl = street.planes
        return StreetExtent(street.name, along, street.cross_index, s, float(pl.facade_min),
                            float(pl.facade_max), float(pl.ground), float(street.start), float(street.end),
                            float(street.center), yaw, oxz, np.array([p.planes.ground for p in probes], np.float64),
                            np.array([p.planes.slope for p in probes], np.float64))

    def to_frame(self, x: ArrayLike) -> NDArray[np.float64]:
        """World points ``x`` (..., 3) in the street's frame."""
        return world_to_frame(x, self.yaw_deg, self.origin_xz)

    def ground_at(self, s: float) -> float:
        """Ground height (m) at along coordinate ``s``: the nearest probe's (tilted) ground where the
        probes' grounds slope or differ from the street's (a street that follows the terrain, flat
        or not), else the street's nominal ground (today's positions)."""
        if (self.probe_ground is None or self.probe_slope is None
                or not (np.any(self.probe_slope) or np.any(self.probe_ground != self.ground))):
            return self.ground
        i = int(np.argmin(np.abs(self.probe_s - s)))
        return float(self.probe_ground[i] + self.probe_slope[i] * (s - self.probe_s[i]))

    def ground_under(self, x: ArrayLike) -> float:
        """Ground height (m) under the world point ``x`` (3,): :meth:`ground_at` its along coordinate
        in the street's frame."""
        return self.ground_at(float(self.to_frame(np.asarray(x, np.float64))[self.along]))

    def contains(self, x: NDArray[np.float64]) -> bool:
        """Whether the world point ``x`` (3,) lies between the facades and the street's ends (any height)."""
        f = self.to_frame(x)
        return bool(self.fmin <= f[self.cross] <= self.fmax and self.start <= f[self.along] <= self.end)

    def position(self, index: int, x: NDArray[np.float64], streets: Sequence["StreetExtent"],
                 height: float | None = None) -> EvalPosition:
        """The :class:`EvalPosition` of the world point ``x`` (3,) on this street (``streets``: all of
        the probe set; ``height`` above the ground if known exactly, else ``x[1]`` - the ground under it)."""
        f = self.to_frame(x)
        return EvalPosition(self.name, index, (float(x[0]), float(x[1]), float(x[2])),
                            float(f[self.cross] - self.center), float(np.min(np.abs(self.probe_s - f[self.along]))),
                            float(x[1] - self.ground_at(f[self.along]) if height is None else height),
                            any(o.contains(x) for o in streets if o.name != self.name), self.yaw_deg)


def street_extent(manifest: Manifest, name: str) -> StreetExtent:
    """The :class:`StreetExtent` of the street ``name`` of a probe-set ``manifest``."""
    for st in manifest.streets:
        if st.name == name:
            return StreetExtent.from_manifest(st)
    raise ValueError(f"probe set has no street named {name!r}")


def _extents(manifest: Manifest) -> list[StreetExtent]:
    streets = manifest.streets
    if not streets:
        raise ValueError("probe set has no streets: nothing to evaluate")
    return [StreetExtent.from_manifest(st) for st in streets]


def sample_positions(manifest: Manifest, sweep: Sweep = DEFAULT_SWEEP) -> list[EvalPosition]:
    """Evaluation positions for every street of a probe-set ``manifest`` (see :class:`Sweep`).

    A street narrower than ``2 * margin`` is sampled on its probe line; one whose usable span is
    empty at the middle of its probes.  Deterministic for a given ``sweep.seed``.
    """
    extents = _extents(manifest)
    out: list[EvalPosition] = []
    for k, ext in enumerate(extents):
        rng = np.random.default_rng(sweep.seed + k)
        s = ext.probe_s
        if manifest.placement is None:   # uniform spacing: the probes' span, half a spacing beyond the end probes
            half = 0.5 * (s[1] - s[0]) if s.size > 1 else 0.5 * float(manifest.probe_spacing)
            lo = max(ext.start + sweep.end_margin, s[0] - half)
            hi = min(ext.end - sweep.end_margin, s[-1] + half)
        else:                            # placed by a strategy: the whole street, whatever the probes chose
            lo, hi = ext.start + sweep.end_margin, ext.end - sweep.end_margin
        if not hi > lo:
            lo = hi = 0.5 * (s[0] + s[-1])
        clo, chi = ext.fmin + sweep.margin, ext.fmax - sweep.margin
        if not chi > clo:
            clo = chi = ext.center
        n = sweep.per_street
        alongs = lo + (hi - lo) * (np.arange(n) + rng.uniform(0, 1, n)) / n
        crosses = rng.uniform(clo, chi, n)
        heights = rng.uniform(sweep.heights[0], sweep.heights[1], n)
        for i in range(n):
            f = np.zeros(3)
            f[ext.along] = alongs[i]
            f[ext.cross] = crosses[i]
            f[1] = ext.ground_at(alongs[i]) + heights[i]
            out.append(ext.position(len(out), frame_to_world(f, ext.yaw_deg, ext.origin_xz), extents, heights[i]))
    return out


def positions_from_array(manifest: Manifest, positions: ArrayLike) -> list[EvalPosition]:
    """:class:`EvalPosition` for explicit world positions ``(P, 3)`` (m): each is assigned to the
    street whose volume holds it, else the street with the nearest probe line."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 1:
        raise ValueError(f"positions must have shape (P, 3) with P >= 1, got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("positions contain NaN or Inf")
    extents = _extents(manifest)

    def cost(ext: StreetExtent, x: NDArray[np.float64]) -> float:
        if ext.contains(x):
            return -1.0
        f = ext.to_frame(x)
        return abs(f[ext.cross] - ext.center) + max(0.0, ext.start - f[ext.along], f[ext.along] - ext.end)

    return [extents[int(np.argmin([cost(e, x) for e in extents]))].position(i, x, extents) for i, x in enumerate(p)]
