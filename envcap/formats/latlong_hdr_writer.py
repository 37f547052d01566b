"""Probe-set writer ``latlong_hdr`` (opt-in: ``envcap capture --latlong-hdr``): the lat-long maps of
the ``latlong`` writer as Radiance RGBE ``.hdr`` files, the format Unreal Engine imports as a
cubemap (``docs/engines.md``, section 5).

* ``latlong/sky.hdr``: the sky, RGB;
* ``latlong/probe_NNN.hdr``: what probe ``NNN`` sees, street + (1 - alpha) sky.

The pixels are :func:`envcap.formats.latlong_writer.latlong_maps`' (``2N x 4N``, OpenEXR's LatLong
orientation: +Y up, the image center looks along +Z, +X a quarter turn to the left of it; row 0
at the top), so a ``.hdr`` and the ``.exr`` of the same name hold the same map, the ``.hdr`` to
RGBE's precision (8-bit mantissas sharing an exponent: relative 2^-8 of a pixel's largest
channel).  Negative values (filtering noise) are stored as 0.  Manifest entries:
``files.latlong_hdr_sky``, ``files.latlong_hdr`` (one path per probe, in layer order).
Parameters: none.

The file: ``#?RADIANCE``, ``FORMAT=32-bit_rle_rgbe``, resolution line ``-Y H +X W`` (rows top
to bottom, columns left to right), then each scanline in Radiance's run-length form with literal
runs only (``2 2 W/256 W%256``, then each of the four byte planes in chunks of at most 128
bytes, each chunk preceded by its length), which no reader can mistake for flat pixels; scanlines
narrower than 8 or wider than 32767 pixels, which that form cannot hold, are flat RGBE.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from envcap.formats.latlong_writer import latlong_maps
from envcap.formats.writer import FileEntries, ProbeSetWriter
from envcap.outputs import atomic_output_file

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet

RLE_MIN, RLE_MAX = 8, 32767
"""Scanline widths Radiance's run-length form holds."""


def rgbe(rgb: NDArray) -> NDArray[np.uint8]:
    """``(..., 3)`` linear radiance -> ``(..., 4)`` RGBE bytes (Ward's shared exponent: the largest
    channel's ``frexp`` exponent + 128; mantissas ``floor(c * 256 / 2^e)``).  Values must be
    finite; negatives and values below 1e-32 store as zero."""
    a = np.maximum(np.asarray(rgb, np.float64), 0.0)
    if not np.isfinite(a).all():
        raise ValueError("RGBE: NaN or Inf in the image")
    v = a.max(axis=-1)
    mant, exp = np.frexp(v)
    scale = np.where(v > 1e-32, mant * 256.0 / np.where(v > 1e-32, v, 1.0), 0.0)
    out = np.zeros(a.shape[:-1] + (4,), np.uint8)
    out[..., :3] = np.clip(np.floor(a * scale[..., None]), 0, 255).astype(np.uint8)
    out[..., 3] = np.where(v > 1e-32, exp + 128, 0).astype(np.uint8)
    return out


def _scanline(row: NDArray[np.uint8]) -> bytes:
    w = row.shape[0]
    if not RLE_MIN <= w <= RLE_MAX:
        return row.tobytes()
    parts = [bytes((2, 2, w >> 8, w & 255))]
    for c in range(4):
        plane = row[:, c].tobytes()
        for k in range(0, w, 128):
            chunk = plane[k:k + 128]
            parts.append(bytes((len(chunk),)) + chunk)
    return b"".join(parts)


def write_hdr(path: str | os.PathLike[str], image: NDArray) -> Path:
    """Write ``image`` ``(H, W, 3)`` (linear RGB, finite) as a Radiance ``.hdr`` file (module
    docstring), atomically; return the path."""
    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] != 3 or min(a.shape[:2]) < 1:
        raise ValueError(f"an .hdr image must have shape (H, W, 3), got {a.shape}")
    px = rgbe(a)
    h, w = a.shape[:2]
    header = f"#?RADIANCE\n# envcap lat-long map (OpenEXR LatLong orientation)\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n"
    body = b"".join(_scanline(px[y]) for y in range(h))
    with atomic_output_file(path) as tmp:
        Path(tmp).write_bytes(header.encode("ascii") + body)
    return Path(path)


def write_latlong_hdr_maps(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the sky's and every probe's lat-long ``.hdr`` under ``out_dir / "latlong"``."""
    (out_dir / "latlong").mkdir(exist_ok=True)
    names = []
    for stem, rgb in latlong_maps(ps):
        write_hdr(out_dir / "latlong" / f"{stem}.hdr", rgb)
        names.append(f"latlong/{stem}.hdr")
    return {"latlong_hdr_sky": names[0], "latlong_hdr": names[1:]}


WRITER = ProbeSetWriter("latlong_hdr", "lat-long Radiance .hdr maps of level 0 (Unreal's cubemap import): the sky and "
                        "each probe over the sky", write_latlong_hdr_maps, default=False)
