"""Bounds before work: what a :class:`~envcap.scene.spec.SceneSpec` will build, counted before any
geometry exists, against the limits of :mod:`envcap.scene.limits` and the memory budget.

:func:`geometry_estimate` gives an upper bound per source (a side's buildings, its windows, a wall's
tiles, the ground's checker tiles); :func:`check_geometry_budget` refuses a scene past
:data:`~envcap.scene.limits.BUILDING_LIMIT` buildings, :data:`~envcap.scene.limits.QUAD_LIMIT`
quads or the memory limit (:func:`envcap.core.budget.check_bytes`) with one line that names the
largest source's keys, the count and what to change.  Counts are exact (up to rounding at a
boundary) for listed buildings, walls and the ground, and upper bounds for random rows (every
building at the minimum width, as tall as the maximum height); a building cut in pieces by a
crossing roadway counts once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from envcap.core.budget import check_bytes, check_count
from envcap.scene.limits import BUILDING_LIMIT, BYTES_PER_QUAD, QUAD_LIMIT
from envcap.scene.spec import (
    FacadeSpec,
    GroundSpec,
    RandomBuildingsSpec,
    SceneSpec,
    SideSpec,
    WallSpec,
    WindowsSpec,
    side_key,
)

QUADS_PER_BUILDING = 5
"""Quads of one building piece: 4 walls and the roof (``docs/scenes.md``, "Buildings")."""


@dataclass(frozen=True)
class Source:
    """One source of geometry: ``count`` elements (``what``) making ``quads`` quads (upper bounds,
    floats: they may be astronomically large), from the table ``where``; ``change`` says which keys
    lower it, ``detail`` how the count comes about."""

    where: str
    what: str
    count: float
    quads: float
    change: str
    detail: str


def _floor(x: float) -> float:
    """``floor(x)`` as a float; a value past 2^53 (or inf) is returned as it is: far past any limit."""
    return float(math.floor(x)) if x < 2.0**53 else x


def _ceil(x: float) -> float:
    return float(math.ceil(x)) if x < 2.0**53 else x


def _times(a: float, b: float) -> float:
    """``a * b`` of two counts, 0 if either is 0 (never ``0 * inf = nan``)."""
    return 0.0 if a == 0 or b == 0 else a * b


def window_floors(w: WindowsSpec, height: float) -> float:
    """Floors with windows on a building ``height`` m tall (the rule of ``docs/scenes.md``, "Windows"):
    ``f = first_floor, ...`` while ``f floor_height + sill + w.height + frame + top_margin <= height``
    (a float: astronomically many floors stay countable)."""
    top = height + 1e-9 - (w.sill + w.height + w.frame + w.top_margin)
    if top < 0:
        return 0.0
    return max(0.0, _floor(top / w.floor_height) - w.first_floor + 1.0)


def _windows(w: WindowsSpec, where: str, count: float, detail: str) -> Source:
    street = where.rsplit(".", 1)[0]
    return Source(where, "windows", count, count * (5.0 if w.frame > 0 else 1.0),
                  f"spacing or floor_height (larger) of {street}.facade.windows or {where}.facade.windows", detail)


def _side_sources(side: SideSpec, where: str, length: float) -> list[Source]:
    """The sources of the side at ``where`` (``streets[0].side_min``) whose buildings start ``length``
    m before the street's end."""
    layout, facade = side.layout, side.facade
    if layout is None:
        return []
    if isinstance(layout, WallSpec):
        tiles = max(1.0, _ceil(length / layout.tile - 1e-9)) * max(1.0, _ceil(layout.height / layout.tile - 1e-9))
        return [Source(f"{where}.wall", "wall tiles", tiles, tiles + 4.0, f"{where}.wall.tile (larger)",
                       f"{length:g} m x {layout.height:g} m in {layout.tile:g} m tiles")]
    if isinstance(layout, RandomBuildingsSpec):
        return _random_sources(layout, facade, where, length)
    out = [Source(f"{where}.buildings", "buildings", len(layout), QUADS_PER_BUILDING * len(layout),
                  f"{where}.buildings (fewer)", f"{len(layout)} listed")]
    w = facade.windows
    if w is not None:
        n = sum(_times(_floor(b.width / w.spacing + 1e-9), window_floors(w, b.height)) for b in layout if b.windows)
        out.append(_windows(w, where, n, f"on {len(layout)} listed buildings"))
    return out


def _random_sources(r: RandomBuildingsSpec, facade: FacadeSpec, where: str, length: float) -> list[Source]:
    n = _floor(length / r.width[0] + 1e-9)
    detail = f"{length:g} m of street at a minimum width of {r.width[0]:g} m"
    if r.count is not None and r.count < n:
        n, detail = float(r.count), f"count = {r.count}"
    out = [Source(f"{where}.random", "buildings", n, QUADS_PER_BUILDING * n,
                  f"{where}.random.width (a larger minimum) or {where}.random.count", detail)]
    w = facade.windows
    if w is not None:
        row = min(length, n * r.width[1])  # along-street meters of facade, at most
        n_windows = _times(_floor(row / w.spacing + 1e-9), window_floors(w, r.height[1]))
        out.append(_windows(w, where, n_windows, f"{row:g} m of facade up to {r.height[1]:g} m high, "
                                                 f"{w.spacing:g} m x {w.floor_height:g} m per window"))
    return out


def _ground_sources(g: GroundSpec | None) -> list[Source]:
    if g is None:
        return []
    if g.checker <= 0:
        return [Source("ground", "ground quads", 1.0, 1.0, "", "one quad")]
    per_axis = max(1.0, _ceil(min(g.checker_extent, g.extent) / g.checker - 1e-9))
    n = per_axis * per_axis
    return [Source("ground", "ground checker tiles", n, n + 4.0, "ground.checker (larger) or ground.checker_extent",
                   f"{min(g.checker_extent, g.extent):g} m square in {g.checker:g} m tiles")]


def geometry_estimate(spec: SceneSpec) -> list[Source]:
    """Every source of the scene's procedural geometry with its counts (imported meshes excluded:
    their size is the file's)."""
    out: list[Source] = []
    for si, s in enumerate(spec.streets):
        for side_index, side in enumerate((s.side_min, s.side_max)):
            if side is not None:
                out += _side_sources(side, side_key(si, side_index), s.street.length - side.start_offset)
    return out + _ground_sources(spec.ground)


def check_geometry_budget(spec: SceneSpec) -> float:
    """Refuse the scene (:class:`~envcap.core.budget.BudgetError`, a ``ValueError``) if its buildings
    or quads pass their limits or its build would pass the memory limit; return the quad estimate.

    The message names the largest source, e.g. ``buildings in the scene (most from
    streets[0].side_min.random: 2e+07 m of street at a minimum width of 0.5 m): 40,000,000 asked,
    more than the limit of 100,000; change streets[0].side_min.random.width (a larger minimum) or
    streets[0].side_min.random.count``."""
    sources = geometry_estimate(spec)
    buildings = [s for s in sources if s.what == "buildings"]
    if buildings:
        big = max(buildings, key=lambda s: s.count)
        check_count(f"buildings in the scene (most from {big.where}: {big.detail})", sum(s.count for s in buildings),
                    BUILDING_LIMIT, big.change)
    if not sources:
        return 0.0
    big = max(sources, key=lambda s: s.quads)
    quads = sum(s.quads for s in sources)
    most = f"most from {big.where}: {big.what}, {big.detail}"
    check_count(f"quads in the scene ({most})", quads, QUAD_LIMIT, big.change)
    check_bytes(f"scene geometry of {quads:,.0f} quads ({most})", quads * BYTES_PER_QUAD, big.change)
    return quads
