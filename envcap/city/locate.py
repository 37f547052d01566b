"""Where an avatar is in a city: world (x, z) -> (street, position in its frame, probe range),
the numpy side of what an engine does with ``street_map.ktx2`` and ``city.json``.

:func:`load_city_map` reads the index and its street map; :meth:`CityMap.locate` looks positions
up (:meth:`envcap.runtime.street_map.StreetMap.lookup`, float32 like the GLSL
``envcap_street_map_id``) and returns, per position, the street index in ``city.json``'s
``streets`` (-1: no street, the sky-only fallback), its frame (``yaw_deg``, ``origin_xz``; 0 and
(0, 0) for a street in the world frame), the position in that frame (``frame_xz`` = (along,
across) for a street at any angle, float64), its local origin (``frame_origin`` (3,) m, frame
coordinates), along axis (0 = x or 2 = z) and its probe range: the shard holding it and the
layers ``[first, first + count)`` inside that shard's ``probes.ktx2`` (and the same range in
city layers).  Between streets (no street's rectangle covers the cell) the result is the
fallback: street -1, the world frame (``frame_xz`` = (x, z)), zero origin, axis -1, shard -1, an
empty range.

:meth:`CityMap.street_table` is the per-id table that GLSL ``envcap_city_locate`` reads (two
small textures), so that the GPU gets the street, its range and the street-local position from
one lookup; :meth:`envcap.runtime.street_map.StreetTable.locate` is its float32 twin.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.city.street_map_file import read_street_map
from envcap.probeset.city_index import INDEX_FILE, CityIndex, read_city_index
from envcap.core.street_frame import yaw_cos_sin
from envcap.runtime.street_map import StreetMap, StreetTable, street_table


@dataclass(frozen=True)
class Located:
    """Per position (arrays of the broadcast shape ``S`` of the inputs): ``street`` int64 (-1 =
    none), ``frame_origin`` ``S + (3,)`` float64 m (the local origin, frame coordinates),
    ``along`` int64 (0, 2; -1 = none), ``shard`` int64 (-1 = none), ``shard_first`` /
    ``city_first`` int64 first layer in the shard / the city, ``count`` int64 layers (0 = none),
    ``yaw_deg`` float64 and ``origin_xz`` ``S + (2,)`` float64 m (the street's frame; 0 for the
    world frame and for none), ``frame_xz`` ``S + (2,)`` float64 m: the position in that frame,
    ``(c dx + s dz, c dz - s dx)`` with ``(dx, dz) = (x, z) - origin_xz`` (``(x, z)`` itself in
    the world frame).  The street-local position is ``frame_xz - frame_origin[..., ::2]``."""

    street: NDArray[np.int64]
    frame_origin: NDArray[np.float64]
    along: NDArray[np.int64]
    shard: NDArray[np.int64]
    shard_first: NDArray[np.int64]
    city_first: NDArray[np.int64]
    count: NDArray[np.int64]
    yaw_deg: NDArray[np.float64]
    origin_xz: NDArray[np.float64]
    frame_xz: NDArray[np.float64]


@dataclass(frozen=True)
class CityMap:
    """A city index and its street map (ids = index in ``index.streets`` + 1)."""

    index: CityIndex
    map: StreetMap

    def __post_init__(self) -> None:
        top = int(self.map.ids.max())
        if top > len(self.index.streets):
            raise ValueError(f"street map holds id {top} but the index lists {len(self.index.streets)} streets")

    def table(self) -> dict[str, NDArray]:
        """Per id (row 0 = no street): the :class:`Located` fields as arrays of length streets + 1."""
        ix = self.index
        n = len(ix.streets) + 1
        t = {"street": np.arange(-1, n - 1, dtype=np.int64), "frame_origin": np.zeros((n, 3)),
             "along": np.full(n, -1, np.int64), "shard": np.full(n, -1, np.int64),
             "shard_first": np.zeros(n, np.int64), "city_first": np.zeros(n, np.int64), "count": np.zeros(n, np.int64),
             "yaw_deg": np.zeros(n), "origin_xz": np.zeros((n, 2))}
        for i, st in enumerate(ix.streets, start=1):
            t["frame_origin"][i] = st.frame_origin
            t["along"][i] = 0 if st.axis == "x" else 2
            t["shard"][i] = st.shard
            t["city_first"][i] = st.layers[0]
            t["shard_first"][i] = st.layers[0] - ix.shards[st.shard].layers[0]
            t["count"][i] = st.layers[1]
            t["yaw_deg"][i] = st.frame_yaw_deg
            t["origin_xz"][i] = st.frame_origin_xz
        return t

    def street_table(self) -> StreetTable:
        """The per-id table of GLSL ``envcap_city_locate`` for this map (upload
        ``StreetTable.textures()``; the range's shard is the index in ``city.json``'s shards)."""
        t = self.table()
        ranges = np.stack([t["shard"], t["shard_first"], t["city_first"], t["count"]], axis=-1)[1:]
        return street_table(t["yaw_deg"][1:], t["origin_xz"][1:], t["frame_origin"][1:], ranges, self.map.origin)

    def locate(self, x: ArrayLike, z: ArrayLike) -> Located:
        """The street, its frame, the position in it and the probe range at world positions
        ``x``, ``z`` (m, broadcastable)."""
        ids = self.map.lookup(x, z).astype(np.int64)
        got = {k: v[ids] for k, v in self.table().items()}
        c, s = yaw_cos_sin(got["yaw_deg"])
        with np.errstate(invalid="ignore", over="ignore"):
            dx = np.asarray(x, np.float64) - got["origin_xz"][..., 0]
            dz = np.asarray(z, np.float64) - got["origin_xz"][..., 1]
            turned = got["yaw_deg"] != 0.0          # the world frame: (dx, dz) exactly, infinities kept
            frame = np.stack([np.where(turned, c * dx + s * dz, dx), np.where(turned, c * dz - s * dx, dz)], axis=-1)
        return Located(**got, frame_xz=frame)


def load_city_map(path: str | os.PathLike[str]) -> CityMap:
    """Read ``city.json`` (the city directory or the file) and the street map it names."""
    p = Path(path)
    root = p if p.is_dir() else p.parent
    index = read_city_index(root / INDEX_FILE if p.is_dir() else p)
    if index.street_map is None:
        raise ValueError(f"{root / INDEX_FILE}: this city has no street map")
    return CityMap(index, read_street_map(root / index.street_map.file, index.street_map))
