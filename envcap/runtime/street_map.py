"""A top-down street-ID map: which street a world position (x, z) is on, for a crowd walking
across a city (issue 11, item 3), and where in that street's frame; the numpy twin of
``shaders/runtime/envcap_street_map.glsl``.

The map is a grid of ``uint16`` street ids (an R16UI texture on the GPU), ``ids[row, column]``
with columns along world +x and rows along world +z: cell ``(i, j)`` covers
``origin + (i, j) * cell <= (x, z) < origin + (i + 1, j + 1) * cell`` (meters).  An id is the
street's index in the probe set's manifest plus 1; 0 means no street.

Rasterization (:func:`street_map`): a cell belongs to a street when the cell's centre lies in the
street's closed rectangle *in the street's frame*: ``p_f = world_to_frame(centre, yaw_deg,
origin_xz)`` (:mod:`envcap.core.street_frame`, float64; the world itself for a street without a
frame) has ``start <= along <= end`` and ``facade_min <= across <= facade_max`` (the street's
nominal planes; along = frame x for a street at any angle).  A centre exactly on an edge is in.
Where rectangles overlap (crossings, at any angle) the cell goes to the street whose centre line
(``Street.center``, in its frame) is nearest to the cell centre (perpendicular distance
``|across - center|``); exact ties go to the lower index.  A street that covers no cell centre
(narrower than a cell) is an error, never dropped silently.

Crossings (optional, :mod:`envcap.probeset.crossings`): with ``crossings`` (the set's meetings,
``n`` streets), a cell whose centre lies in crossing ``k``'s region (where the corridors of two of
its streets overlap; overlapping regions: the nearest centre) gets id ``n + 1 + k`` instead of a
street's, so that one lookup tells a crossing from its streets: :func:`crossing_index` (GLSL
``envcap_street_map_crossing``) gives ``k`` (-1 for a street or none).  The crossing's probe and
streets are ``Manifest.crossings[k]`` (docs/crossings.md).  A map without crossings is unchanged.

Lookup (:meth:`StreetMap.lookup`, GLSL ``envcap_street_map_id``), in float32 like the GPU:
``u = floor((p - origin) * inv_cell)`` with ``p = (x, z)``, ``origin`` and ``inv_cell = 1 / cell``
rounded to float32; the id of cell ``u`` when ``0 <= u < (columns, rows)``, else 0 (outside the
grid, NaN and infinite positions included).  A position exactly on a cell boundary belongs to the
cell above it (floor), exactly so when ``cell`` is a power of two (``inv_cell`` exact); for other
cell sizes the rounding of ``inv_cell`` may move a boundary by one float32 step, identically in
GLSL and numpy.  Positions are float32 in the map's frame: keep ``origin`` near them (a city
in projected coordinates passes positions relative to a local origin, as the runtime's
street-local frames do).

Locate (:class:`StreetTable`, GLSL ``envcap_city_locate``): per id, the street's frame and probe
range, so that one lookup gives the street, the position in its street-local frame and its probe
layers.  Row ``id`` (0 = no street) holds ``(cos yaw, sin yaw)``, a translation ``t`` (3,) and
``(shard, first layer in the shard, first layer in the city, count)``.  With ``d = (x, z) -
origin`` (float32, as for the cell) the street-local position is, in float32::

    local = (c d.x + s d.y + t.x,  y + t.y,  c d.y - s d.x + t.z)

where ``t = R (M - O) - L`` was computed in float64 and rounded once (``M`` = the map origin as
float32, ``O`` = the street's frame origin ``(ox, 0, oz)``, ``L`` = its local origin in frame
coordinates, the runtime's ``street_origin``): ``local = R (p - O) - L``, what
``StreetUniforms.to_local`` gives for the street's uniforms.  Row 0 (no street, the sky-only
fallback) is the identity with ``t = 0``: ``local = (x - origin.x, y, z - origin.z)`` and range
``(0, 0, 0, 0)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.street_frame import world_to_frame, yaw_cos_sin
from envcap.probeset.city_index import street_bounds
from envcap.probeset.crossings import Meeting, corridor, crossing_of
from envcap.probeset.manifest import Street

MAX_STREETS = 65535      # uint16 ids, 0 reserved for "no street"
TABLE_WIDTH = 1024       # columns of the locate tables' textures (GL ES 3.0 guarantees 2048)
MAX_MAP_SIZE = 16384     # texels per side of the map: GL_MAX_TEXTURE_SIZE of most GPUs (docs/scale.md, Limits)


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


def crossing_index(ids: ArrayLike, street_count: int) -> NDArray[np.int64]:
    """Per street-map id: the crossing index ``k`` (id ``street_count + 1 + k``), -1 for a street or
    none; the numpy twin of GLSL ``envcap_street_map_crossing``."""
    i = np.asarray(ids, np.int64)
    return np.where(i > street_count, i - street_count - 1, -1)


def street_map(streets: Sequence[Street], cell: float, *, origin: tuple[float, float] | None = None,
               size: tuple[int, int] | None = None, crossings: Sequence[Meeting] = ()) -> StreetMap:
    """Rasterize ``streets`` (a manifest's ``streets``, id = index + 1, at any angle) into a
    :class:`StreetMap` of ``cell`` meters (rule: the module docstring).  By default the grid is
    the smallest one on multiples of ``cell`` that holds every street's world box
    (:func:`envcap.probeset.city_index.street_bounds`); ``origin`` (x, z) and ``size`` (columns,
    rows) set it instead.  Each street is tested on the cells of its world box only.  ``crossings``:
    the meetings of ``streets`` (:func:`envcap.probeset.crossings.detect_crossings`, or
    :func:`envcap.probeset.crossings.meetings_of` a manifest's table), rasterized over the streets'
    cells as ids ``len(streets) + 1 + k`` (module docstring).  A grid past
    :data:`MAX_MAP_SIZE` texels per side is a ``ValueError`` (naming ``--map-cell`` and the smallest
    cell that fits) before anything is allocated."""
    if not streets:
        raise ValueError("a street map needs at least one street")
    if len(streets) + len(crossings) > MAX_STREETS:
        raise ValueError(f"{len(streets)} streets and {len(crossings)} crossings do not fit in uint16 ids "
                         f"(at most {MAX_STREETS})")
    if not (math.isfinite(cell) and cell > 0):
        raise ValueError(f"cell must be a positive finite size in meters, got {cell}")
    boxes = np.array([street_bounds(st) for st in streets], dtype=np.float64)
    extent = (float(boxes[:, 1].max() - boxes[:, 0].min()), float(boxes[:, 3].max() - boxes[:, 2].min()))
    if size is None:   # before floor / ceil: a tiny cell overflows them
        _check_map_size((extent[0] / cell, extent[1] / cell), cell, *extent)
    if origin is None:
        origin = (math.floor(boxes[:, 0].min() / cell) * cell, math.floor(boxes[:, 2].min() / cell) * cell)
    if size is None:
        size = (max(1, math.ceil((boxes[:, 1].max() - origin[0]) / cell)),
                max(1, math.ceil((boxes[:, 3].max() - origin[1]) / cell)))
    _check_map_size(size, cell, *extent)
    w, h = size
    cx = origin[0] + (np.arange(w) + 0.5) * cell          # cell centres, float64
    cz = origin[1] + (np.arange(h) + 0.5) * cell
    best = np.full((h, w), np.inf)
    ids = np.zeros((h, w), dtype=np.uint16)
    for k, (st, (x0, x1, z0, z1)) in enumerate(zip(streets, boxes)):
        # the cells whose centres may lie in the rectangle: its world box, one cell of margin
        i0, i1 = np.searchsorted(cx, [x0 - cell, x1 + cell])
        j0, j1 = np.searchsorted(cz, [z0 - cell, z1 + cell])
        X, Z = np.meshgrid(cx[i0:i1], cz[j0:j1])             # (rows, columns) of the window
        f = world_to_frame(np.stack([X, np.zeros_like(X), Z], axis=-1), st.frame_yaw_deg, st.frame_origin_xz)
        along, across = f[..., st.along_index], f[..., st.cross_index]
        covered = ((along >= st.start) & (along <= st.end)
                   & (across >= st.planes.facade_min) & (across <= st.planes.facade_max))
        if not covered.any():
            raise ValueError(f"street {k} ({st.name!r}) covers no cell centre at cell {cell} m: use a smaller cell")
        dist = np.abs(across - st.center)
        win_best, win_ids = best[j0:j1, i0:i1], ids[j0:j1, i0:i1]  # views
        take = covered & (dist < win_best)                 # strict: ties stay with the lower index
        win_best[take] = dist[take]
        win_ids[take] = k + 1
    if crossings:
        _rasterize_crossings(ids, streets, boxes, crossings, cx, cz, cell)
    return StreetMap(ids=ids, origin=(float(origin[0]), float(origin[1])), cell=float(cell))


def _rasterize_crossings(ids: NDArray[np.uint16], streets: Sequence[Street], boxes: NDArray[np.float64],
                         crossings: Sequence[Meeting], cx: NDArray[np.float64], cz: NDArray[np.float64], cell: float) -> None:
    """Write crossing ids into ``ids`` (in place): each crossing tested on the cells of the world box
    of its region (the union of its streets' pairwise box overlaps), nearest centre first."""
    n = len(streets)
    bad = [m.streets for m in crossings if len(m.streets) < 2 or not all(0 <= i < n for i in m.streets)]
    if bad:
        raise ValueError(f"crossings name streets {bad[0]} of a map of {n} streets (need two or more of them)")
    cors = [corridor(st) for st in streets]
    best = np.full(ids.shape, np.inf)
    for k, m in enumerate(crossings):
        b = boxes[list(m.streets)]
        pairs = [(max(p[0], q[0]), min(p[1], q[1]), max(p[2], q[2]), min(p[3], q[3]))
                 for a, p in enumerate(b) for q in b[a + 1:]]
        pairs = [w for w in pairs if w[0] <= w[1] and w[2] <= w[3]]
        if not pairs:
            continue
        x0, x1 = min(w[0] for w in pairs), max(w[1] for w in pairs)
        z0, z1 = min(w[2] for w in pairs), max(w[3] for w in pairs)
        i0, i1 = np.searchsorted(cx, [x0 - cell, x1 + cell])
        j0, j1 = np.searchsorted(cz, [z0 - cell, z1 + cell])
        X, Z = np.meshgrid(cx[i0:i1], cz[j0:j1])
        inside = crossing_of(cors, [m], np.stack([X, Z], axis=-1)) == 0
        dist = np.hypot(X - m.centre[0], Z - m.centre[1])
        win_best, win_ids = best[j0:j1, i0:i1], ids[j0:j1, i0:i1]     # views
        take = inside & (dist < win_best)                            # strict: ties stay with the lower index
        win_best[take] = dist[take]
        win_ids[take] = n + 1 + k


def _check_map_size(size: tuple[float, float], cell: float, extent_x: float, extent_z: float) -> None:
    """``ValueError`` (one line, naming ``--map-cell``) for a grid past :data:`MAX_MAP_SIZE` texels per
    side, before anything is allocated; ``extent_*``: the streets' world box (m), for the advice."""
    w, h = float(size[0]), float(size[1])
    if w <= MAX_MAP_SIZE and h <= MAX_MAP_SIZE:
        return
    # with the origin on a multiple of the cell, ceil(extent / c) + 1 <= MAX_MAP_SIZE cells hold the box
    need = max(extent_x, extent_z) / (MAX_MAP_SIZE - 1)
    fit = float(f"{need:.3g}")
    fit = fit if fit >= need else float(f"{need * 1.001:.3g}")
    raise ValueError(f"street map (--map-cell, map_cell) at cell {cell:g} m would be {w:.0f} x {h:.0f} texels, past "
                     f"{MAX_MAP_SIZE} per side (the texture limit of most GPUs); use a cell of at least {fit:g} m")


@dataclass(frozen=True)
class StreetTable:
    """Per street id (row 0 = no street; see the module docstring): ``frames`` ``(n + 1, 2, 4)``
    float32, texel 0 = ``(cos yaw, sin yaw, t.x, t.z)``, texel 1 = ``(t.y, 0, 0, 0)`` (``t`` in
    m); ``ranges`` ``(n + 1, 4)`` uint32 ``(shard, first layer in the shard, first layer in the
    city, count)``.  Made for one map origin (:func:`street_table`)."""

    frames: NDArray[np.float32]
    ranges: NDArray[np.uint32]

    def __post_init__(self) -> None:
        n = self.frames.shape[0]
        if self.frames.shape != (n, 2, 4) or self.frames.dtype != np.float32 or n < 1:
            raise ValueError(f"frames must be (n + 1, 2, 4) float32, got {self.frames.dtype} {self.frames.shape}")
        if self.ranges.shape != (n, 4) or self.ranges.dtype != np.uint32:
            raise ValueError(f"ranges must be ({n}, 4) uint32, got {self.ranges.dtype} {self.ranges.shape}")

    def textures(self, width: int = TABLE_WIDTH) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """The two textures GLSL ``envcap_city_locate`` reads: ``frames`` RGBA32F and ``ranges``
        RGBA32UI, each ``(rows, columns, 4)``, texel ``i`` at ``(i % columns, i // columns)``
        (the frames' texels of id ``k`` are ``2k`` and ``2k + 1``), at most ``width`` columns,
        zero-padded.  Upload with NEAREST filtering; read with ``texelFetch``."""
        if not (isinstance(width, (int, np.integer)) and width >= 2):
            raise ValueError(f"table texture width must be an integer >= 2 texels, got {width!r}")

        def wrap(a: NDArray) -> NDArray:
            cols = min(len(a), width)
            out = np.zeros((-(-len(a) // cols) * cols, 4), a.dtype)
            out[:len(a)] = a
            return out.reshape(-1, cols, 4)
        return wrap(self.frames.reshape(-1, 4)), wrap(self.ranges)

    def locate(self, m: StreetMap, x: ArrayLike, y: ArrayLike, z: ArrayLike
               ) -> tuple[NDArray[np.uint16], NDArray[np.uint32], NDArray[np.float32]]:
        """The GLSL ``envcap_city_locate`` in numpy, float32 operation for operation: per position
        (world m, broadcast shape ``S``) the street id (0 = none), its range ``S + (4,)`` and the
        street-local position ``S + (3,)`` (float32; module docstring)."""
        ids = m.lookup(x, z)
        o = np.asarray(m.origin, dtype=np.float32)
        x32, y32, z32 = np.broadcast_arrays(*(np.asarray(v, dtype=np.float32) for v in (x, y, z)))
        f = self.frames[ids.astype(np.int64)]
        c, s, tx, tz, ty = f[..., 0, 0], f[..., 0, 1], f[..., 0, 2], f[..., 0, 3], f[..., 1, 0]
        with np.errstate(invalid="ignore", over="ignore"):
            dx, dz = x32 - o[0], z32 - o[1]
            local = np.stack([c * dx + s * dz + tx, y32 + ty, c * dz - s * dx + tz], axis=-1)
        return ids, self.ranges[ids.astype(np.int64)], local


def street_table(yaw_deg: ArrayLike, origin_xz: ArrayLike, local_origin: ArrayLike, ranges: ArrayLike,
                 map_origin: tuple[float, float]) -> StreetTable:
    """The :class:`StreetTable` of ``n`` streets (id ``k + 1`` = row ``k`` of the arguments):
    ``yaw_deg`` (n,) degrees, ``origin_xz`` (n, 2) m (frame origins; 0 for a street in the world
    frame), ``local_origin`` (n, 3) m (each street's local origin in its frame coordinates),
    ``ranges`` (n, 4) ``(shard, shard first, city first, count)``, for a map whose origin is
    ``map_origin``.  ``t`` is computed in float64 and rounded to float32 once."""
    yaw = np.asarray(yaw_deg, np.float64).reshape(-1)
    n = yaw.size
    o = np.asarray(origin_xz, np.float64).reshape(n, 2)
    lo = np.asarray(local_origin, np.float64).reshape(n, 3)
    c, s = yaw_cos_sin(yaw)
    mx, mz = (float(v) for v in np.asarray(map_origin, np.float32))   # the origin GLSL subtracts
    vx, vz = mx - o[:, 0], mz - o[:, 1]
    frames = np.zeros((n + 1, 2, 4), np.float64)
    frames[0, 0, 0] = 1.0
    frames[1:, 0] = np.stack([c, s, c * vx + s * vz - lo[:, 0], c * vz - s * vx - lo[:, 2]], axis=-1)
    frames[1:, 1, 0] = -lo[:, 1]
    r = np.zeros((n + 1, 4), np.int64)
    r[1:] = np.asarray(ranges, np.int64).reshape(n, 4)
    if r.min() < 0 or r.max() > np.iinfo(np.uint32).max:
        raise ValueError("street ranges must be non-negative 32-bit integers")
    return StreetTable(frames=frames.astype(np.float32), ranges=r.astype(np.uint32))
