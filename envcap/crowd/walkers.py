"""Walkers on a street's sidewalks: placement and motion, seeded and reproducible.

A street (:class:`envcap.runtime.street.StreetProbes`, any frame: yaw'd and on terrain too) has an
along range (its probes' along coordinates) and, per probe, facade planes on the cross axis and a
ground ``ground0 + slope * s``.  Each walker walks on one of the two sidewalks (the strip
``SIDEWALK`` m wide inside each facade, its own lateral offset in it), in one of the two
directions along the street, at its own speed (``SPEED`` m/s) from its own start and gait phase;
a walker that leaves the along range comes back in at the other end (the crowd stays on the
street at every time).  Its feet stand on the ground: the manifest's ground under it (the nearest
probe's plane with its slope), or the scene's ground mesh there when a height function is given
(:class:`envcap.scene.ground_height.GroundHeights`; NaN where the mesh has none: the manifest's).

Conventions: world meters, +Y up; a walker's heading is the yaw (rad, about +Y) that turns the
avatar's forward +Z (glTF) onto its walking direction: ``(sin h, 0, cos h)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from envcap.core.street_frame import frame_to_world, from_frame
from envcap.runtime.street import StreetProbes

SIDEWALK = (0.8, 2.8)
"""Distance (m) of a walker's path from its facade: between these."""
SPEED = (0.9, 1.6)
"""Walking speeds (m/s), uniform between these."""
SPACING = 1.2
"""Metres of street per walker in the default span (both sidewalks together)."""
MIN_SPAN = 30.0
"""Shortest default span (m)."""
GROUND_LIFT = 0.0
"""Height (m) of the feet above the ground (the avatar's feet are at its y = 0)."""

GroundFn = Callable[[NDArray[np.float64]], NDArray[np.float64]]
"""World plan points ``(P, 2)`` (x, z) m -> ground heights ``(P,)`` m (NaN: unknown)."""


@dataclass(frozen=True)
class Walkers:
    """``N`` walkers on one street.  Per walker: ``side`` (-1: along the facade_min sidewalk, +1:
    facade_max), ``offset`` (m from its facade), ``start`` (along coordinate at time 0, m, the
    street's frame), ``direction`` (+1 / -1 along the street), ``speed`` (m/s), ``phase`` (s into
    the gait cycle at time 0).  ``street``: the probes whose planes and grounds they stand on;
    ``seed``: what drew them; ``span``: the along range (m, frame) they walk in; ``ground``: the
    scene's ground (optional)."""

    street: StreetProbes
    side: NDArray[np.int64]
    offset: NDArray[np.float64]
    start: NDArray[np.float64]
    direction: NDArray[np.int64]
    speed: NDArray[np.float64]
    phase: NDArray[np.float64]
    seed: int
    span: tuple[float, float]
    ground: GroundFn | None = None

    def __len__(self) -> int:
        return int(self.side.size)

    @property
    def along_range(self) -> tuple[float, float]:
        """``(s0, s1)`` the along coordinates (m, frame) the walkers keep within."""
        return self.span

    def along(self, time: float) -> NDArray[np.float64]:
        """``(N,)`` along coordinates (m, the street's frame) at ``time`` s (wrapped into the range)."""
        s0, s1 = self.along_range
        length = max(s1 - s0, 1e-6)
        return s0 + np.mod(self.start - s0 + self.direction * self.speed * float(time), length)

    def nearest_probe(self, s: NDArray[np.float64]) -> NDArray[np.int64]:
        """Index of the probe nearest each along coordinate ``s``."""
        a = self.street.positions[:, self.street.along]
        return np.argmin(np.abs(a[None, :] - s[:, None]), axis=1)

    def positions(self, time: float) -> NDArray[np.float64]:
        """``(N, 3)`` world positions (m) of the walkers' feet at ``time`` s."""
        return self.on_street(self.along(time), self.side, self.offset)

    def on_street(self, s: NDArray[np.float64], side: NDArray[np.int64], offset: NDArray[np.float64]) -> NDArray[np.float64]:
        """World points (m) on the ground at along coordinates ``s``, ``offset`` m inside the
        facade of ``side`` (-1 facade_min, +1 facade_max; 0: the street's centre line)."""
        st = self.street
        s = np.asarray(s, np.float64)
        side = np.broadcast_to(side, s.shape)
        offset = np.broadcast_to(offset, s.shape)
        k = self.nearest_probe(s)
        planes = st.planes[k]
        cross = np.where(side < 0, planes[:, 0] + offset,
                         np.where(side > 0, planes[:, 1] - offset, (planes[:, 0] + planes[:, 1]) / 2))
        slopes = st.slopes if st.slopes is not None else np.zeros(len(st.layers))
        ground = planes[:, 2] + slopes[k] * (s - st.positions[k, st.along])
        f = np.zeros((len(s), 3))
        f[:, st.along] = s
        f[:, 2 - st.along] = cross
        f[:, 1] = ground
        world = frame_to_world(f, st.yaw_deg, st.origin_xz)
        if self.ground is not None:
            h = np.asarray(self.ground(world[:, [0, 2]]), np.float64).reshape(-1)
            world[:, 1] = np.where(np.isfinite(h), h, world[:, 1])
        world[:, 1] += GROUND_LIFT
        return world

    def headings(self) -> NDArray[np.float64]:
        """``(N,)`` yaw (rad) of each walker (constant: walkers keep to their sidewalk)."""
        axis = np.zeros(3)
        axis[self.street.along] = 1.0
        world_axis = from_frame(axis[None], self.street.yaw_deg)[0]
        fwd = world_axis[None, :] * self.direction[:, None]
        return np.arctan2(fwd[:, 0], fwd[:, 2])


def default_span(street: StreetProbes, count: int) -> tuple[float, float]:
    """The along range a crowd of ``count`` walks in: :data:`SPACING` m of street per walker
    (at least :data:`MIN_SPAN` m), centred on the street, at most the whole street."""
    s = street.positions[:, street.along]
    lo, hi = float(s.min()), float(s.max())
    length = min(hi - lo, max(MIN_SPAN, SPACING * count))
    mid = (lo + hi) / 2
    return mid - length / 2, mid + length / 2


def place_walkers(street: StreetProbes, count: int, seed: int = 0, ground: GroundFn | None = None,
                  span: tuple[float, float] | None = None) -> Walkers:
    """``count`` walkers on ``street`` drawn from ``seed`` (module docstring) in ``span`` (default
    :func:`default_span`): sides and directions half and half (shuffled), starts spread evenly
    with a random jitter of up to half their spacing, offsets, speeds and phases uniform."""
    if count < 0:
        raise ValueError(f"--avatars must be >= 0, got {count}")
    rng = np.random.default_rng(seed)
    s0, s1 = default_span(street, count) if span is None else (float(span[0]), float(span[1]))
    gap = (s1 - s0) / max(count, 1)
    start = s0 + gap * (np.arange(count) + 0.5 + rng.uniform(-0.5, 0.5, count))
    side = np.where(rng.permutation(count) % 2 == 0, -1, 1).astype(np.int64)
    direction = np.where(rng.permutation(count) % 2 == 0, 1, -1).astype(np.int64)
    return Walkers(street, side, rng.uniform(*SIDEWALK, count), start, direction, rng.uniform(*SPEED, count),
                   rng.uniform(0.0, 1.0, count), int(seed), (s0, s1), ground)


def yaw_matrices(headings: NDArray[np.float64], positions: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(N, 4, 4)`` root transforms: turn by ``headings`` (rad about +Y) then move to ``positions``."""
    c, s = np.cos(headings), np.sin(headings)
    m = np.zeros((len(headings), 4, 4))
    m[:, 0, 0], m[:, 0, 2], m[:, 2, 0], m[:, 2, 2] = c, s, -s, c
    m[:, 1, 1] = m[:, 3, 3] = 1.0
    m[:, :3, 3] = positions
    return m


def describe(walkers: Walkers) -> str:
    """One line: how many, the street's along range and frame."""
    s0, s1 = walkers.along_range
    return (f"{len(walkers)} walkers on street {walkers.street.name!r} along {s0:.1f}..{s1:.1f} m "
            f"(yaw {walkers.street.yaw_deg:g} deg), seed {walkers.seed}")

