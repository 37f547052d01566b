"""A top-down street-ID map: which street a world position (x, z) is on, for a crowd walking
across a city (issue 11, item 3); the numpy twin of ``shaders/runtime/envcap_street_map.glsl``.

The map is a grid of ``uint16`` street ids (an R16UI texture on the GPU), ``ids[row, column]``
with columns along world +x and rows along world +z: cell ``(i, j)`` covers
``origin + (i, j) * cell <= (x, z) < origin + (i + 1, j + 1) * cell`` (meters).  An id is the
street's index in the probe set's manifest plus 1; 0 means no street.

Rasterization (:func:`street_map`): a cell belongs to a street when the cell's centre lies in the
street's closed footprint, ``start <= along <= end`` and ``facade_min <= across <= facade_max``
(the street's nominal planes).  Where footprints overlap (crossings) the cell goes to the street
whose centre line (``Street.center``) is nearest to the cell centre; ties go to the lower index.
A street that covers no cell centre (narrower than a cell) is an error, never dropped silently.

Lookup (:meth:`StreetMap.lookup`, GLSL ``envcap_street_map_id``), in float32 like the GPU:
``u = floor((p - origin) * inv_cell)`` with ``p = (x, z)``, ``origin`` and ``inv_cell = 1 / cell``
rounded to float32; the id of cell ``u`` when ``0 <= u < (columns, rows)``, else 0 (outside the
grid, NaN and infinite positions included).  A position exactly on a cell boundary belongs to the
cell above it (floor), exactly so when ``cell`` is a power of two (``inv_cell`` exact); for other
cell sizes the rounding of ``inv_cell`` may move a boundary by one float32 step, identically in
GLSL and numpy.  Positions are float32 in the map's frame: keep ``origin`` near them (a city
in projected coordinates passes positions relative to a local origin, as the runtime's
street-local frames do).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.probeset.manifest import Street

MAX_STREETS = 65535      # uint16 ids, 0 reserved for "no street"


@dataclass(frozen=True)
class StreetMap:
    """Street ids ``(rows, columns)`` uint16 (rows along +z, columns along +x), the world (x, z)
    of the grid's low corner ``origin`` (m) and the square cell size ``cell`` (m)."""

    ids: NDArray[np.uint16]
    origin: tuple[float, float]
    cell: float

    def __post_init__(self) -> None:
        if self.ids.dtype != np.uint16 or self.ids.ndim != 2 or 0 in self.ids.shape:
            raise ValueError(f"ids must be a non-empty 2-D uint16 array, got {self.ids.dtype} {self.ids.shape}")
        if not (math.isfinite(self.cell) and self.cell > 0):
            raise ValueError(f"cell must be a positive finite size in meters, got {self.cell}")

    @property
    def size(self) -> tuple[int, int]:
        """Texture size ``(width = columns, height = rows)``."""
        return int(self.ids.shape[1]), int(self.ids.shape[0])

    @property
    def inv_cell(self) -> np.float32:
        """``1 / cell`` rounded to float32: the GLSL lookup's scale (exact for a power-of-two cell)."""
        return np.float32(1.0 / self.cell)

    def glsl_arguments(self) -> tuple[tuple[float, float], float]:
        """``(origin, inv_cell)`` as float32 values for ``envcap_street_map_id(map, origin, inv_cell, xz)``."""
        o = np.asarray(self.origin, dtype=np.float32)
        return (float(o[0]), float(o[1])), float(self.inv_cell)

    def cell_of(self, x: ArrayLike, z: ArrayLike) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """Cell coordinates ``(floor column, floor row)`` of positions, float32 as in GLSL (may be
        outside the grid, NaN for NaN input)."""
        o = np.asarray(self.origin, dtype=np.float32)
        s = self.inv_cell
        u = np.floor((np.asarray(x, dtype=np.float32) - o[0]) * s)
        v = np.floor((np.asarray(z, dtype=np.float32) - o[1]) * s)
        return u, v

    def lookup(self, x: ArrayLike, z: ArrayLike) -> NDArray[np.uint16]:
        """Street id (0 = none) at world positions ``x``, ``z`` (m, any broadcastable shapes)."""
        with np.errstate(invalid="ignore", over="ignore"):
            u, v = self.cell_of(x, z)
            w, h = self.size
            inside = (u >= 0) & (v >= 0) & (u < np.float32(w)) & (v < np.float32(h))
        out = np.zeros(np.broadcast(u, v).shape, dtype=np.uint16)
        uu, vv = np.broadcast_arrays(u, v)
        out[inside] = self.ids[vv[inside].astype(np.int64), uu[inside].astype(np.int64)]
        return out


def _footprint(st: Street) -> tuple[float, float, float, float]:
    """``(x_min, x_max, z_min, z_max)`` of a street's closed footprint (m)."""
    lo, hi = st.planes.facade_min, st.planes.facade_max
    return (st.start, st.end, lo, hi) if st.axis == "x" else (lo, hi, st.start, st.end)


def street_map(streets: Sequence[Street], cell: float, *, origin: tuple[float, float] | None = None,
               size: tuple[int, int] | None = None) -> StreetMap:
    """Rasterize ``streets`` (a manifest's ``streets``, id = index + 1) into a :class:`StreetMap`
    of ``cell`` meters.  By default the grid is the smallest one on multiples of ``cell`` that
    holds every footprint; ``origin`` (x, z) and ``size`` (columns, rows) set it instead."""
    if not streets:
        raise ValueError("a street map needs at least one street")
    if len(streets) > MAX_STREETS:
        raise ValueError(f"{len(streets)} streets do not fit in uint16 ids (at most {MAX_STREETS})")
    if not (math.isfinite(cell) and cell > 0):
        raise ValueError(f"cell must be a positive finite size in meters, got {cell}")
    boxes = np.array([_footprint(st) for st in streets], dtype=np.float64)
    if origin is None:
        origin = (math.floor(boxes[:, 0].min() / cell) * cell, math.floor(boxes[:, 2].min() / cell) * cell)
    if size is None:
        size = (max(1, math.ceil((boxes[:, 1].max() - origin[0]) / cell)),
                max(1, math.ceil((boxes[:, 3].max() - origin[1]) / cell)))
    w, h = size
    cx = origin[0] + (np.arange(w) + 0.5) * cell          # cell centres, float64
    cz = origin[1] + (np.arange(h) + 0.5) * cell
    X, Z = np.meshgrid(cx, cz)                             # (rows, columns)
    best = np.full((h, w), np.inf)
    ids = np.zeros((h, w), dtype=np.uint16)
    for k, (st, (x0, x1, z0, z1)) in enumerate(zip(streets, boxes)):
        covered = (X >= x0) & (X <= x1) & (Z >= z0) & (Z <= z1)
        if not covered.any():
            raise ValueError(f"street {k} ({st.name!r}) covers no cell centre at cell {cell} m: use a smaller cell")
        dist = np.abs((Z if st.axis == "x" else X) - st.center)
        take = covered & (dist < best)                     # strict: ties stay with the lower index
        best[take] = dist[take]
        ids[take] = k + 1
    return StreetMap(ids=ids, origin=(float(origin[0]), float(origin[1])), cell=float(cell))
