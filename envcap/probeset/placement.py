"""Probe placement along a street's center line.

A street (:class:`envcap.scene.model.Street`) has a probe line along its center at a fixed
height.  Each probe records its nominal planes (:class:`envcap.probeset.planes.Planes`, from the
street description); the bake fits its own planes from its capture
(:func:`envcap.probeset.planes.fit_planes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.budget import check_count
from envcap.core.checks import format_number
from envcap.probeset.planes import Planes
from envcap.scene.model import Street

SLOPE_STEP_MIN_M = 2.0
"""Shortest half-baseline (m) of a probe's nominal terrain slope (:func:`slope_step`): shorter
would read curbs and mesh steps as slope."""

MAX_PROBES = 100_000
"""Most probes one bake places (all streets together, and on one street), unless the caller
raises it (``max_probes`` of :func:`place_probes` and
:func:`envcap.probeset.bake.bake_probe_set`).  At llvmpipe rates 10^5 probes take hours even
at 4^2 texels per face; a GPU's cube-map array holds far fewer (docs/reliability.md, Limits)."""


@dataclass(frozen=True)
class ProbePlacement:
    """One probe: its street, index along the street, world position (m) and nominal planes."""

    street: str
    index: int
    position: tuple[float, float, float]
    planes: Planes


def _plain(value: object) -> str:
    """A number as a user typed it (``1e+30``, ``nan``, ``5``), anything else as its repr."""
    return format_number(value) if isinstance(value, (int, float, np.number)) and not isinstance(value, bool) else repr(value)


def check_spacing(spacing: float) -> float:
    """``spacing`` (m) as a float: finite and > 0 (``ValueError`` naming the probe spacing)."""
    if not (isinstance(spacing, (int, float)) and math.isfinite(spacing) and spacing > 0):
        raise ValueError(f"probe spacing (--spacing) must be a positive number of meters, got {_plain(spacing)}")
    return float(spacing)


def probe_count(street: Street, spacing: float) -> float:
    """How many probes :func:`place_probes` puts on ``street`` at ``spacing`` m: ``max(1,
    floor(length / spacing))``, as a float that may be huge or ``inf`` (``1e300`` m of street at
    ``1e-9`` m), so that it can be bounded before any probe exists."""
    per = street.length / check_spacing(spacing) + 1e-9
    return float(max(1, math.floor(per))) if math.isfinite(per) else math.inf


def place_probes(street: Street, spacing: float = 5.0, height: float = 2.0, *,
                 max_probes: int = MAX_PROBES,
                 ground_at: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None) -> list[ProbePlacement]:
    """Probes along ``street``'s center line at ``height`` m above its ground, ``spacing`` m apart.

    The ground is ``street.ground``, or, for a street that follows the terrain
    (``street.follow_terrain``), ``ground_at(xz)`` under each probe ((P, 2) plan points -> (P,)
    heights, NaN where there is none: e.g. :func:`envcap.scene.ground_height.ground_heights`);
    each probe's nominal ground plane is then at its own ground, with the terrain's slope along the
    street there (:func:`terrain_slopes`, ``Planes.ground_slope``; ``None`` for other streets).
    A framed street (``street.framed``) places its probes in its frame (along frame x at the
    centre line's frame z) and turns them to world positions (float64).

    The probes are spaced exactly ``spacing`` apart and centered on the street: there are
    ``max(1, floor(length / spacing))`` of them (:func:`probe_count`), so that each stands at
    least ``spacing / 2`` from the street's ends (a street shorter than ``spacing`` gets one probe
    at its middle).  The height must lie strictly between the ground and 1 km; the spacing must be
    positive; more than ``max_probes`` probes are refused before any is placed
    (:class:`envcap.core.budget.BudgetError`, naming ``--spacing``).
    """
    check_spacing(spacing)
    check_height(height)
    count = check_count(f"probes on street '{street.name}' ({street.length:g} m at spacing {spacing:g} m)",
                        probe_count(street, spacing), max_probes, "--spacing")
    return place_probes_at(street, uniform_along(street, count, spacing), height, ground_at=ground_at, slope_spacing=spacing)


def uniform_along(street: Street, count: int, spacing: float | None = None) -> NDArray[np.float64]:
    """(count,) along-street coordinates (m, the street's frame) of ``count`` probes ``spacing`` m
    apart centred on the street (default spacing: ``length / count``, so that the probes stand
    ``spacing / 2`` from both ends): the positions of :func:`place_probes`."""
    spacing = street.length / count if spacing is None else spacing
    mid = 0.5 * (street.start + street.end)
    return mid + (np.arange(count) - 0.5 * (count - 1)) * spacing


def check_height(height: float) -> float:
    """``height`` (m above the ground) as a float: in (0, 1000) (``ValueError`` naming ``--height``)."""
    if not (isinstance(height, (int, float)) and math.isfinite(height) and 0 < height < 1000):
        raise ValueError(f"probe height (--height) must be in (0, 1000) m above the ground, got {_plain(height)}")
    return float(height)


def check_along(street: Street, along: ArrayLike) -> NDArray[np.float64]:
    """``along`` as a (P,) float64 array of probe coordinates (m, the street's frame) on ``street``:
    at least one, finite, strictly increasing, within ``[start, end]`` (``ValueError`` naming the
    street and the first bad value)."""
    a = np.asarray(along, dtype=np.float64).reshape(-1)
    if a.size < 1:
        raise ValueError(f"street '{street.name}': no probe positions given")
    bad = np.flatnonzero(~np.isfinite(a) | (a < street.start) | (a > street.end))
    if bad.size:
        raise ValueError(f"street '{street.name}': probe {int(bad[0])} at {_plain(float(a[bad[0]]))} m lies outside "
                         f"the street ({street.start:g} .. {street.end:g} m along it)")
    if np.any(np.diff(a) <= 0):
        i = int(np.flatnonzero(np.diff(a) <= 0)[0])
        raise ValueError(f"street '{street.name}': probe positions must increase along the street, "
                         f"probe {i + 1} ({a[i + 1]:g} m) follows {a[i]:g} m")
    return a


def place_probes_at(street: Street, along: ArrayLike, height: float = 2.0, *,
                    ground_at: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
                    slope_spacing: float | None = None) -> list[ProbePlacement]:
    """Probes on ``street``'s center line at the along-street coordinates ``along`` (m, the
    street's frame; :func:`check_along`), ``height`` m above its ground: the positions a placement
    strategy chose (:mod:`envcap.placement`); :func:`place_probes` is this at uniform coordinates.

    Ground, terrain and frames as :func:`place_probes`; a terrain-following street's nominal
    slope is measured over ``slope_spacing`` (m; default the mean spacing ``length / P``,
    :func:`slope_step`)."""
    check_height(height)
    along = check_along(street, along)
    count = along.size
    spacing = street.length / count if slope_spacing is None else float(slope_spacing)
    xz = _plan_points(street, along)
    grounds = np.full(count, float(street.ground))
    slopes: list[float | None] = [None] * count
    if street.follow_terrain:
        if ground_at is None:
            raise ValueError(f"street '{street.name}' follows the terrain: probe placement needs the scene's mesh")
        grounds = np.asarray(ground_at(xz), np.float64).reshape(count)
        missing = np.flatnonzero(~np.isfinite(grounds))
        if missing.size:
            i = int(missing[0])
            raise ValueError(f"street '{street.name}' follows the terrain, but no up-facing surface lies under probe {i} "
                             f"at x = {xz[i, 0]:.2f}, z = {xz[i, 1]:.2f} m ({missing.size} probes without ground)")
        slopes = list(terrain_slopes(street, along, grounds, spacing, ground_at))
    out = []
    for i in range(count):
        pos = (float(xz[i, 0]), float(grounds[i]) + height, float(xz[i, 1]))
        planes = Planes(street.facade_min, street.facade_max, float(grounds[i]), slopes[i])
        out.append(ProbePlacement(street.name, i, pos, planes))
    return out


def _plan_points(street: Street, along: NDArray[np.float64]) -> NDArray[np.float64]:
    """(P, 2) world plan points (x, z), m, of the centre line at the ``along`` coordinates (the
    street's own frame for a framed street, turned to the world in float64)."""
    loc = np.zeros((len(along), 3))
    loc[:, street.along_index] = along
    loc[:, street.cross_index] = street.center_line
    return street.to_world(loc)[:, [0, 2]]


def slope_step(spacing: float) -> float:
    """Half the baseline (m) of a probe's nominal terrain slope: ``max(spacing / 2,``
    :data:`SLOPE_STEP_MIN_M` ``)``: the slope is the mean over the probe's own stretch of street."""
    return max(0.5 * float(spacing), SLOPE_STEP_MIN_M)


def terrain_slopes(street: Street, along: NDArray[np.float64], grounds: NDArray[np.float64], spacing: float,
                   ground_at: Callable[[NDArray[np.float64]], NDArray[np.float64]]) -> NDArray[np.float64]:
    """(P,) nominal ground slope (m per m along the street's +along axis) at each probe: the
    central difference ``(g(s + h) - g(s - h)) / 2h`` of the terrain heights on the centre line,
    ``h =`` :func:`slope_step` (``spacing``); one-sided against the probe's own ground
    ``grounds`` where one end has no ground, 0 where neither has.  ``along`` (P,) are the probes'
    along coordinates; ``ground_at`` maps (Q, 2) world plan points to heights (NaN: none)."""
    h = slope_step(spacing)
    ends = ground_at(_plan_points(street, np.concatenate([along - h, along + h])))
    lo, hi = np.split(np.asarray(ends, np.float64).reshape(-1), 2)
    central = (hi - lo) / (2 * h)
    out = np.where(np.isfinite(central), central,
                   np.where(np.isfinite(hi), (hi - grounds) / h, np.where(np.isfinite(lo), (grounds - lo) / h, 0.0)))
    return out + 0.0
