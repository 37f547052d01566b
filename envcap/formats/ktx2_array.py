"""KTX 2.0 files for float 2D texture arrays of one mip level (the WebGL2 face atlases).

The same subset of the KTX 2.0 specification as :mod:`envcap.formats.ktx2` (same Data Format
Descriptor and key/value data: ``KTXorientation = "rd"``, ``KTXwriter``, nothing else by
default), with ``faceCount = 1``, ``pixelDepth = 0``, ``layerCount = L`` and ``levelCount = 1``.
The level holds the layers in order, each ``H`` rows (row 0 first) of ``W`` RGBA texels: the C
order of a numpy array ``(L, H, W, 4)``, uploadable as-is with
``texImage3D(TEXTURE_2D_ARRAY, 0, RGBA16F, W, H, L, 0, RGBA, HALF_FLOAT, data)``.
"""

from __future__ import annotations

import math
import os
import struct
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from envcap.formats.ktx2 import FORMATS, HALF_MAX, IDENTIFIER, basic_dfd, key_value_data
from envcap.outputs import atomic_output_file

_HEADER = struct.Struct("<12s9I4I2Q")
_LEVEL = struct.Struct("<3Q")


def write_ktx2_array(path: str | os.PathLike[str], image: NDArray, *, fmt: str = "rgba16f",
                     premultiplied: bool = False, kv: dict[str, str] | None = None) -> Path:
    """Write ``image`` ``(L, H, W, 4)`` (float, finite; ``rgba16f`` values within +-65504) as a
    KTX2 2D texture array of one level, atomically; return the path.  ``premultiplied`` sets the
    DFD's alpha-premultiplied flag; ``kv`` adds key/value strings (none by default: the KTX
    specification defines no key for them, and ``ktx validate`` warns about custom keys)."""
    if fmt not in ("rgba16f", "rgba32f"):
        raise ValueError(f"KTX2 texture arrays are RGBA: fmt must be 'rgba16f' or 'rgba32f', got {fmt!r}")
    a = np.asarray(image)
    if a.ndim != 4 or a.shape[-1] != 4 or min(a.shape[:3]) < 1:
        raise ValueError(f"a KTX2 texture array must have shape (L, H, W, 4) with L, H, W >= 1, got {a.shape}")
    if not np.issubdtype(a.dtype, np.floating):
        raise ValueError(f"KTX2 texture array: expected a floating-point array, got dtype {a.dtype}")
    bad = int(a.size - np.count_nonzero(np.isfinite(a)))
    if bad:
        raise ValueError(f"KTX2 texture array: {bad} value(s) are NaN or Inf")
    vk_format, comp = FORMATS[fmt]
    if comp is np.float16 and np.any(np.abs(a) > HALF_MAX):
        raise ValueError(f"KTX2 texture array: values exceed the half-float maximum {HALF_MAX:g}; use fmt='rgba32f'")
    data = np.ascontiguousarray(a, dtype=np.dtype(comp).newbyteorder("<")).tobytes()
    layers, h, w = a.shape[:3]
    dfd = basic_dfd(fmt, premultiplied)
    kvd = key_value_data(kv)
    dfd_off = _HEADER.size + _LEVEL.size
    kvd_off = dfd_off + len(dfd)
    align = math.lcm(4 * np.dtype(comp).itemsize, 4)
    level_off = (kvd_off + len(kvd) + align - 1) // align * align
    header = _HEADER.pack(IDENTIFIER, vk_format, np.dtype(comp).itemsize, w, h, 0, layers, 1, 1, 0,
                          dfd_off, len(dfd), kvd_off, len(kvd), 0, 0)
    body = header + _LEVEL.pack(level_off, len(data), len(data)) + dfd + kvd
    final = Path(path)
    with atomic_output_file(final) as tmp:
        with open(tmp, "wb") as f:
            f.write(body + b"\0" * (level_off - len(body)))
            f.write(data)
    return final
