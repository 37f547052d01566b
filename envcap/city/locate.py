"""Where an avatar is in a city: world (x, z) -> (street, local frame, probe range), the numpy
side of what an engine does with ``street_map.ktx2`` and ``city.json``.

:func:`load_city_map` reads the index and its street map; :meth:`CityMap.locate` looks positions
up (:meth:`envcap.runtime.street_map.StreetMap.lookup`, float32 like the GLSL
``envcap_street_map_id``) and returns, per position, the street index in ``city.json``'s
``streets`` (-1: no street, the sky-only fallback), its local frame (origin (3,) m, along axis 0 =
x or 2 = z) and its probe range: the shard holding it and the layers ``[first, first + count)``
inside that shard's ``probes.ktx2`` (and the same range in city layers).  Between streets (no
street's footprint covers the cell) the result is the fallback: street -1, zero origin, axis -1,
shard -1, an empty range.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.city.street_map_file import read_street_map
from envcap.probeset.city_index import INDEX_FILE, CityIndex, read_city_index
from envcap.runtime.street_map import StreetMap


@dataclass(frozen=True)
class Located:
    """Per position (arrays of the broadcast shape ``S`` of the inputs): ``street`` int64 (-1 =
    none), ``frame_origin`` ``S + (3,)`` float64 m, ``along`` int64 (0, 2; -1 = none), ``shard``
    int64 (-1 = none), ``shard_first`` / ``city_first`` int64 first layer in the shard / the
    city, ``count`` int64 layers (0 = none)."""

    street: NDArray[np.int64]
    frame_origin: NDArray[np.float64]
    along: NDArray[np.int64]
    shard: NDArray[np.int64]
    shard_first: NDArray[np.int64]
    city_first: NDArray[np.int64]
    count: NDArray[np.int64]


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
             "shard_first": np.zeros(n, np.int64), "city_first": np.zeros(n, np.int64), "count": np.zeros(n, np.int64)}
        for i, st in enumerate(ix.streets, start=1):
            t["frame_origin"][i] = st.frame_origin
            t["along"][i] = 0 if st.axis == "x" else 2
            t["shard"][i] = st.shard
            t["city_first"][i] = st.layers[0]
            t["shard_first"][i] = st.layers[0] - ix.shards[st.shard].layers[0]
            t["count"][i] = st.layers[1]
        return t

    def locate(self, x: ArrayLike, z: ArrayLike) -> Located:
        """The street, local frame and probe range at world positions ``x``, ``z`` (m)."""
        ids = self.map.lookup(x, z).astype(np.int64)
        return Located(**{k: v[ids] for k, v in self.table().items()})


def load_city_map(path: str | os.PathLike[str]) -> CityMap:
    """Read ``city.json`` (the city directory or the file) and the street map it names."""
    p = Path(path)
    root = p if p.is_dir() else p.parent
    index = read_city_index(root / INDEX_FILE if p.is_dir() else p)
    if index.street_map is None:
        raise ValueError(f"{root / INDEX_FILE}: this city has no street map")
    sm = read_street_map(root / index.street_map.file)
    info = index.street_map
    if sm.ids.shape != (info.size[1], info.size[0]) or sm.origin != info.origin or sm.cell != info.cell:
        raise ValueError(f"{root / info.file}: {sm.size} cells of {sm.cell} m at {sm.origin} disagree with "
                         f"{INDEX_FILE}'s {info.size} cells of {info.cell} m at {info.origin}")
    return CityMap(index, sm)
