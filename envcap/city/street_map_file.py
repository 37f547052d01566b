"""The street map on disk: a KTX 2.0 file holding one 2-D ``VK_FORMAT_R16_UINT`` image, written by
the one KTX2 container writer (:mod:`envcap.formats.ktx2_container`, ``docs/formats.md``).

* header: ``vkFormat = 74`` (R16_UINT), ``typeSize = 2``, ``pixelWidth`` = columns (world +x),
  ``pixelHeight`` = rows (world +z), ``pixelDepth = layerCount = 0``, ``faceCount = 1``,
  ``levelCount = 1``, no supercompression;
* data format descriptor: one basic block, model RGBSDA, primaries and transfer function
  UNSPECIFIED (KTX 2.0 §3.10.1: integer formats), one 16-bit unsigned integer sample on channel
  R with ``sampleLower = 0``, ``sampleUpper = 1`` (what ``vk2dfd`` builds for R16_UINT);
* key/value data: ``KTXorientation = "rd"`` (row 0 first: row ``r`` of the file is texel row
  ``t = r``, the cells of ``z`` in ``origin_z + [r, r + 1) * cell``) and ``KTXwriter``, nothing else;
* one level: ``rows x columns`` little-endian ``uint16`` street ids (0 = no street).

The map's ``origin`` and ``cell`` (meters) are in ``city.json`` (``street_map``: ``file``, ``origin``,
``cell``, ``size``; :class:`envcap.probeset.city_index.StreetMapInfo`), the one place that says
what the file is: :func:`read_street_map` takes them from there.

Upload: ``glTexImage2D(GL_TEXTURE_2D, 0, GL_R16UI, columns, rows, 0, GL_RED_INTEGER,
GL_UNSIGNED_SHORT, data)``; sample with ``texelFetch`` (``shaders/runtime/envcap_street_map.glsl``).
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from envcap.formats.ktx2_container import R16_UINT, Ktx2Shape, array_levels, ktx2_bytes, read_ktx2_file
from envcap.outputs import atomic_output_file
from envcap.probeset.city_index import StreetMapInfo
from envcap.runtime.street_map import StreetMap

DFD_BEFORE_ISSUE_19 = struct.pack("<11I", 44, 0, (40 << 16) | 2, 1 | (1 << 16), 0, 2, 0, 15 << 16, 0, 0, 65535)
"""The DFD envcap wrote for the street map before issue 19 (version 0.1.0): primaries unspecified
but transfer LINEAR, and ``sampleUpper = 65535`` where ``ktx validate`` expects 1 (error 6028).
Such a file (which also carries the custom key ``envcapStreetMap`` with the origin and cell)
still reads: its ids are the same, the DFD says nothing the reader needs, and origin and cell
come from ``city.json``, which those versions wrote too
(``tests/formats/data/street_map_before_issue19.ktx2``)."""


def _shape(sm: StreetMap) -> Ktx2Shape:
    w, h = sm.size
    return Ktx2Shape(R16_UINT, w, h)


def street_map_bytes(sm: StreetMap) -> bytes:
    """The whole KTX2 file of ``sm``'s ids (see the module docstring)."""
    shape = _shape(sm)
    return ktx2_bytes(shape, array_levels([sm.ids], shape))


def write_street_map(path: str | os.PathLike[str], sm: StreetMap) -> Path:
    """Write ``sm``'s ids as a KTX2 file at ``path``, atomically; return the path.  Its origin and
    cell go in ``city.json`` (:class:`envcap.probeset.city_index.StreetMapInfo`)."""
    with atomic_output_file(path) as tmp:
        tmp.write_bytes(street_map_bytes(sm))
    return Path(path)


def read_street_map(path: str | os.PathLike[str], info: StreetMapInfo) -> StreetMap:
    """The street map of the KTX2 file at ``path`` with ``info``'s origin and cell (``city.json``).
    ``FileNotFoundError``; ``ValueError`` naming the file and the field that is not what
    :func:`write_street_map` writes, or the size that disagrees with ``info``."""
    got = read_ktx2_file(path, formats=[R16_UINT], faces=1, what="street map", legacy_dfds=[DFD_BEFORE_ISSUE_19])
    s = got.shape
    if s.layers != 0 or s.levels != 1:
        raise ValueError(f"street map {path}: layerCount {s.layers}, levelCount {s.levels}; "
                         "a street map is one 2-D image of one level")
    if (s.width, s.height) != tuple(info.size):
        raise ValueError(f"street map {path}: {s.width} x {s.height} cells, "
                         f"city.json says {info.size[0]} x {info.size[1]}")
    ids = np.array(got.levels[0][0, 0, :, :, 0], dtype=np.uint16)
    return StreetMap(ids=ids, origin=(float(info.origin[0]), float(info.origin[1])), cell=float(info.cell))
