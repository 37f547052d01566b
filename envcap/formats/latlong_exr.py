"""Lat-long (equirectangular) OpenEXR environment maps of envcap cubes, for tools that take only
lat-long maps (Godot's ``PanoramaSkyMaterial``, Unity's Latitude-Longitude cubemap import,
OpenImageIO's ``TextureSystem.environment``; see ``docs/engines.md``).

Orientation: OpenEXR's ``LatLong`` convention (:mod:`envcap.core.latlong`): +Y up, the image
center looks along +Z, +X a quarter turn to the left of it; the file's ``envmap`` attribute says
``LATLONG``.  Pixel centers sit at ``u = (x + 1/2) / W``, ``v = (y + 1/2) / H``.  Each pixel is
the seamless bilinear cube lookup at its center direction (:func:`envcap.core.cube_sampling.sample_cube`,
the float64 twin of the GL sampler), so the map holds the cube's values, not a re-filtered copy.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube_sampling
from envcap.core.checks import positive_int
from envcap.core.cube import check_cube
from envcap.core.latlong import latlong_directions
from envcap.core.street_frame import to_frame
from envcap.outputs import atomic_output_file

HALF_MAX = 65504.0


def cube_to_latlong_seamless(cube: NDArray, height: int | None = None, yaw_deg: float = 0.0) -> NDArray[np.float32]:
    """The lat-long map ``(H, 2H, C)`` of cube ``(6, N, N, C)`` by seamless bilinear lookups at
    the pixel centers; ``height`` defaults to ``2 N`` (about the cube's texel density at the
    equator).  ``yaw_deg``: the cube's faces lie along the frame of a street at that angle
    (:mod:`envcap.core.street_frame`, a probe of a street at an angle); the map is in the world's
    orientation all the same (pixel direction ``d`` looks the cube up at ``R d``)."""
    c = check_cube(cube)
    h = positive_int(2 * c.shape[1] if height is None else height, "lat-long height")
    d = latlong_directions(h, 2 * h)
    return cube_sampling.sample_cube([np.asarray(c, np.float64)], to_frame(d, yaw_deg) if yaw_deg else d).astype(np.float32)


def write_latlong_exr(path: str | os.PathLike[str], image: NDArray, *, half: bool | None = None) -> Path:
    """Write lat-long ``image`` ``(H, W, 3 or 4)`` (RGB or RGBA, finite) as a scanline OpenEXR file
    with ``envmap = LATLONG``, atomically; return the path.  ``half``: store half floats (values
    beyond +-65504 raise ``ValueError``), float32 (``False``) or half when every value fits
    (``None``)."""
    import OpenEXR

    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] not in (3, 4) or min(a.shape[:2]) < 1:
        raise ValueError(f"a lat-long image must have shape (H, W, 3) or (H, W, 4), got {a.shape}")
    a = a.astype(np.float64)
    bad = int(a.size - np.count_nonzero(np.isfinite(a)))
    if bad:
        raise ValueError(f"lat-long image: {bad} value(s) are NaN or Inf")
    over = int(np.count_nonzero(np.abs(a) > HALF_MAX))
    if half is None:
        half = over == 0
    if half and over:
        raise ValueError(f"lat-long image: {over} value(s) exceed the half-float maximum {HALF_MAX:g}; use half=False")
    if np.any(np.abs(a) > np.finfo(np.float32).max):
        raise ValueError("lat-long image: values exceed the float32 range")
    dtype = np.float16 if half else np.float32
    channels = {ch: np.ascontiguousarray(a[..., i].astype(dtype)) for i, ch in enumerate("RGBA"[: a.shape[2]])}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_LATLONG}
    final = Path(path)
    with atomic_output_file(final) as tmp:
        OpenEXR.File(header, channels).write(str(tmp))
    return final
