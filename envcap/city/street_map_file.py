"""The street map on disk: a KTX 2.0 file holding one 2-D ``VK_FORMAT_R16_UINT`` image.

Written from the Khronos KTX 2.0 specification (https://registry.khronos.org/KTX/specs/2.0/) and
the Khronos Data Format specification 1.3, as :mod:`envcap.formats.ktx2` does for cube maps:

* header: ``vkFormat = 74`` (R16_UINT), ``typeSize = 2``, ``pixelWidth`` = columns (world +x),
  ``pixelHeight`` = rows (world +z), ``pixelDepth = layerCount = 0``, ``faceCount = 1``,
  ``levelCount = 1``, no supercompression;
* data format descriptor: one basic block, model RGBSDA, unspecified primaries, linear
  transfer, one 16-bit unsigned integer sample on channel R (``sampleLower = 0``,
  ``sampleUpper = 65535``);
* key/value data: ``KTXorientation = "rd"`` (row 0 first: row ``r`` of the file is texel row
  ``t = r``, the cells of ``z`` in ``origin_z + [r, r + 1) * cell``), ``KTXwriter``, and
  ``envcapStreetMap``: JSON ``{"origin": [x, z], "cell": c}`` (meters), so that the file alone
  is a complete :class:`envcap.runtime.street_map.StreetMap`;
* one level: ``rows x columns`` little-endian ``uint16`` street ids (0 = no street).

Upload: ``glTexImage2D(GL_TEXTURE_2D, 0, GL_R16UI, columns, rows, 0, GL_RED_INTEGER,
GL_UNSIGNED_SHORT, data)``; sample with ``texelFetch`` (``shaders/runtime/envcap_street_map.glsl``).
"""

from __future__ import annotations

import json
import math
import os
import struct
from pathlib import Path

import numpy as np

from envcap import __version__
from envcap.outputs import atomic_output_file
from envcap.runtime.street_map import StreetMap

IDENTIFIER = b"\xabKTX 20\xbb\r\n\x1a\n"
VK_FORMAT_R16_UINT = 74
KV_KEY = "envcapStreetMap"

_HEADER = struct.Struct("<12s9I4I2Q")
_LEVEL = struct.Struct("<3Q")


def _pad4(b: bytes) -> bytes:
    return b + b"\0" * (-len(b) % 4)


def _dfd() -> bytes:
    """The basic data format descriptor (with its leading ``dfdTotalSize``) of R16_UINT."""
    block = 24 + 16
    words = [0,                          # vendor Khronos (0), descriptor type basic (0)
             (block << 16) | 2,          # version 1.3, descriptor block size
             1 | (0 << 8) | (1 << 16),   # model RGBSDA, primaries unspecified, transfer linear, no flags
             0,                          # texel block 1x1x1x1
             2, 0,                       # bytesPlane0 = 2
             (15 << 16) | (0 << 24),     # sample: bitOffset 0, bitLength 16 (-1), channel R, unsigned int
             0, 0, 65535]                # samplePosition, sampleLower, sampleUpper
    body = struct.pack(f"<{len(words)}I", *words)
    return struct.pack("<I", 4 + len(body)) + body


def _kvd(kv: dict[str, str]) -> bytes:
    out = b""
    for k, v in sorted(kv.items()):
        payload = k.encode() + b"\0" + v.encode() + b"\0"
        out += _pad4(struct.pack("<I", len(payload)) + payload)
    return out


def street_map_bytes(sm: StreetMap) -> bytes:
    """The whole KTX2 file of ``sm`` (see the module docstring)."""
    h, w = sm.ids.shape
    meta = json.dumps({"origin": [float(sm.origin[0]), float(sm.origin[1])], "cell": float(sm.cell)})
    dfd = _dfd()
    kvd = _kvd({"KTXorientation": "rd", "KTXwriter": f"envcap {__version__}", KV_KEY: meta})
    data = np.ascontiguousarray(sm.ids, dtype="<u2").tobytes()
    dfd_off = _HEADER.size + _LEVEL.size
    kvd_off = dfd_off + len(dfd)
    data_off = kvd_off + len(kvd)
    data_off += -data_off % 4
    head = _HEADER.pack(IDENTIFIER, VK_FORMAT_R16_UINT, 2, w, h, 0, 0, 1, 1, 0,
                        dfd_off, len(dfd), kvd_off, len(kvd), 0, 0)
    level = _LEVEL.pack(data_off, len(data), len(data))
    body = head + level + dfd + kvd
    return body + b"\0" * (data_off - len(body)) + data


def write_street_map(path: str | os.PathLike[str], sm: StreetMap) -> Path:
    """Write ``sm`` as a KTX2 file at ``path``, atomically; return the path."""
    with atomic_output_file(path) as tmp:
        tmp.write_bytes(street_map_bytes(sm))
    return Path(path)


def read_street_map(path: str | os.PathLike[str]) -> StreetMap:
    """Read a street-map KTX2 file (``FileNotFoundError``; ``ValueError`` naming the file and
    the field that is not what :func:`write_street_map` writes)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"street map not found: {p}")
    raw = p.read_bytes()
    if len(raw) < _HEADER.size + _LEVEL.size or raw[:12] != IDENTIFIER:
        raise ValueError(f"{p}: not a KTX 2.0 file")
    (_, fmt, tsize, w, h, depth, layers, faces, levels, sc,
     _, _, kvd_off, kvd_len, _, _) = _HEADER.unpack_from(raw, 0)
    want = dict(vkFormat=(fmt, VK_FORMAT_R16_UINT), typeSize=(tsize, 2), pixelDepth=(depth, 0),
                layerCount=(layers, 0), faceCount=(faces, 1), levelCount=(levels, 1), supercompressionScheme=(sc, 0))
    for name, (got, exp) in want.items():
        if got != exp:
            raise ValueError(f"{p}: {name} is {got}, a street map has {exp} (2-D R16_UINT, one level)")
    if w < 1 or h < 1:
        raise ValueError(f"{p}: empty street map ({w} x {h})")
    off, length, _ = _LEVEL.unpack_from(raw, _HEADER.size)
    if length != 2 * w * h or off + length > len(raw):
        raise ValueError(f"{p}: level 0 holds {length} bytes at {off}, need {2 * w * h} within {len(raw)}")
    kv = {}
    pos, end = kvd_off, min(kvd_off + kvd_len, len(raw))
    while pos + 4 <= end:
        (n,) = struct.unpack_from("<I", raw, pos)
        k, _, v = raw[pos + 4:pos + 4 + n].partition(b"\0")
        kv[k.decode(errors="replace")] = v.rstrip(b"\0").decode(errors="replace")
        pos += 4 + n + (-(4 + n) % 4)
    try:
        meta = json.loads(kv[KV_KEY])
        origin = (float(meta["origin"][0]), float(meta["origin"][1]))
        cell = float(meta["cell"])
    except (KeyError, ValueError, TypeError, IndexError):
        raise ValueError(f"{p}: missing or bad {KV_KEY!r} key/value entry (origin and cell of the map)") from None
    if not all(math.isfinite(x) for x in (*origin, cell)):
        raise ValueError(f"{p}: {KV_KEY} origin and cell must be finite, got {origin}, {cell}")
    ids = np.frombuffer(raw, dtype="<u2", count=w * h, offset=off).reshape(h, w).astype(np.uint16)
    return StreetMap(ids=ids, origin=origin, cell=cell)
