"""Lat-long (equirectangular) environment maps in OpenEXR's ``LatLong`` convention.

Convention (``ImfEnvmap.cpp``, namespace ``LatLongMap``), world frame +Y up:

* A direction of latitude ``lat`` and longitude ``lon`` is
  ``(sin(lon) cos(lat), sin(lat), cos(lon) cos(lat))``.  ``lon = 0`` is +Z, ``lon = +pi/2`` is +X.
* An image is ``(H, W, C)`` indexed ``[row y, column x, channel]``.  Latitude is +pi/2 at the top
  (row 0) and -pi/2 at the bottom; longitude *decreases* left to right, +pi at the left edge,
  0 (direction +Z) in the middle, -pi at the right edge.
* envcap samples at texel centers: with ``u = (x + 0.5) / W`` and ``v = (y + 0.5) / H``,
  ``lon = -2 pi (u - 1/2)`` and ``lat = -pi (v - 1/2)``.  OpenEXR itself puts the first and last
  pixel *on* the edges (``u = x / (W - 1)``); ``centers=False`` gives those positions, which is
  what ``exrenvmap`` uses when it reads or writes a lat-long file.
* Continuous pixel coordinates (:func:`direction_to_latlong_xy`) put pixel ``(x, y)``'s center at
  the integer point ``(x, y)``; pixel ``x`` covers ``[x - 1/2, x + 1/2)``.

Azimuth in envcap (``envcap.sky.sky``) is the longitude: measured from +Z towards +X.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Callable

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from envcap.core import cube as _cube

__all__ = [
    "latlong_directions",
    "direction_to_latlong",
    "direction_to_latlong_xy",
    "latlong_solid_angles",
    "sample_latlong",
    "cube_texel_average",
    "latlong_to_cube",
    "cube_to_latlong",
    "read_latlong",
    "load_latlong",
]


def _check_hw(h: int, w: int) -> tuple[int, int]:
    for name, v in (("height", h), ("width", w)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
            raise ValueError(f"lat-long {name} must be a positive integer, got {v!r}")
    return int(h), int(w)


def latlong_directions(h: int, w: int, centers: bool = True) -> NDArray[np.float64]:
    """Unit directions of every pixel of an ``h`` x ``w`` lat-long map, shape ``(h, w, 3)``, float64.

    ``centers=True``: texel centers ``u = (x + 0.5) / w`` (envcap's sampling positions).
    ``centers=False``: OpenEXR's edge-to-edge positions ``u = x / (w - 1)`` (and ``v`` alike);
    a one-pixel axis gets ``u = 1/2`` (OpenEXR sets the angle to 0 there).
    """
    h, w = _check_hw(h, w)
    if centers:
        u = (np.arange(w, dtype=np.float64) + 0.5) / w
        v = (np.arange(h, dtype=np.float64) + 0.5) / h
    else:
        u = np.arange(w, dtype=np.float64) / (w - 1) if w > 1 else np.full(1, 0.5)
        v = np.arange(h, dtype=np.float64) / (h - 1) if h > 1 else np.full(1, 0.5)
    lon = -2.0 * np.pi * (u - 0.5)
    lat = -np.pi * (v - 0.5)
    cl = np.cos(lat)[:, None]
    out = np.empty((h, w, 3), dtype=np.float64)
    out[..., 0] = np.sin(lon)[None, :] * cl
    out[..., 1] = np.sin(lat)[:, None]
    out[..., 2] = np.cos(lon)[None, :] * cl
    return out


def _check_dirs(d: NDArray) -> NDArray[np.float64]:
    d = np.asarray(d, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"directions must have shape (..., 3), got {d.shape}")
    if not np.all(np.isfinite(d)):
        raise ValueError("directions contain NaN or Inf")
    if np.any(np.all(d == 0, axis=-1)):
        raise ValueError("zero-length direction has no latitude or longitude")
    return d


def direction_to_latlong(d: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Latitude and longitude (radians) of directions ``d`` of shape ``(..., 3)`` (any length > 0).

    ``lat`` in [-pi/2, pi/2], ``lon = atan2(x, z)`` in [-pi, pi] (0 at the poles).  Computed with
    ``atan2`` so it is accurate near the poles.  Zero or non-finite directions raise ``ValueError``.
    """
    d = _check_dirs(d)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    lat = np.arctan2(y, np.hypot(x, z))
    lon = np.arctan2(x, z)  # atan2(0, 0) = 0, as OpenEXR
    return lat, lon


def direction_to_latlong_xy(d: NDArray, h: int, w: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Continuous pixel coordinates ``(x, y)`` of directions ``d`` (``(..., 3)``) in an ``h`` x ``w`` map.

    Pixel ``(x, y)``'s center is at the integer point; ``x`` in [-1/2, w - 1/2], ``y`` in
    [-1/2, h - 1/2].  Inverse of :func:`latlong_directions` (``centers=True``).
    """
    h, w = _check_hw(h, w)
    lat, lon = direction_to_latlong(d)
    u = 0.5 - lon / (2.0 * np.pi)
    v = 0.5 - lat / np.pi
    return u * w - 0.5, v * h - 0.5


def latlong_solid_angles(h: int, w: int) -> NDArray[np.float64]:
    """Exact solid angle (sr) of every pixel of an ``h`` x ``w`` lat-long map, shape ``(h, w)``.

    Row ``y`` spans latitudes ``[lat1, lat0] = [pi/2 - (y+1) pi/h, pi/2 - y pi/h]`` and each pixel
    ``2 pi / w`` of longitude: ``omega = (2 pi / w) (sin lat0 - sin lat1)``, evaluated as
    ``2 cos(mid) sin(half)`` to avoid cancellation.  They sum to 4 pi.
    """
    h, w = _check_hw(h, w)
    half = 0.5 * np.pi / h
    mid = 0.5 * np.pi - (np.arange(h, dtype=np.float64) + 0.5) * np.pi / h
    row = (2.0 * np.pi / w) * 2.0 * np.cos(mid) * np.sin(half)
    return np.broadcast_to(row[:, None], (h, w)).copy()


def _check_image(img: NDArray, name: str = "lat-long image") -> NDArray:
    a = np.asarray(img)
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 1 or a.shape[2] < 1:
        raise ValueError(f"{name} must have shape (H, W, C), got {a.shape}")
    return a


def sample_latlong(img: NDArray, d: NDArray) -> NDArray[np.float64]:
    """Bilinear lookup of a lat-long map ``img`` (``(H, W, C)``) at directions ``d`` (``(..., 3)``).

    Longitude wraps around (the left and right edges are neighbours); latitude clamps to the
    first/last row's center (above the top row's center the top row's value is returned).
    Returns ``(..., C)`` float64.
    """
    a = _check_image(img)
    h, w, c = a.shape
    x, y = direction_to_latlong_xy(d, h, w)
    x0 = np.floor(x)
    fx = x - x0
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y = np.clip(y, 0.0, h - 1.0)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 1)
    fy = y - y0
    y1 = np.minimum(y0 + 1, h - 1)
    a64 = a.astype(np.float64, copy=False)
    fx = fx[..., None]
    fy = fy[..., None]
    top = a64[y0, x0] * (1.0 - fx) + a64[y0, x1] * fx
    bot = a64[y1, x0] * (1.0 - fx) + a64[y1, x1] * fx
    return top * (1.0 - fy) + bot * fy


def cube_texel_average(fn: Callable[[NDArray[np.float64]], NDArray], n: int, supersample: int = 4,
                       desc: str | None = None) -> NDArray[np.float64]:
    """Solid-angle-weighted texel averages of a function of direction over an ``n``-texel cube.

    ``fn`` maps unit directions ``(..., 3)`` float64 to values ``(..., C)``.  Each texel is split
    into ``supersample`` x ``supersample`` equal sub-squares in face coordinates; each sub-sample is
    weighted by the solid-angle density ``(1 + u^2 + v^2)^(-3/2)`` and the weights are normalised
    per texel.  Returns ``(6, n, n, C)`` float64 (envcap cube layout).  A tqdm bar shows progress.
    """
    n = _cube._check_size(n)
    if not isinstance(supersample, (int, np.integer)) or isinstance(supersample, bool) or supersample < 1:
        raise ValueError(f"supersample must be a positive integer, got {supersample!r}")
    ss = int(supersample)
    base = np.arange(n, dtype=np.float64)
    faces = np.arange(6)[:, None, None]
    acc = None
    wsum = np.zeros((1, n, n, 1), dtype=np.float64)
    offsets = [((a + 0.5) / ss, (b + 0.5) / ss) for a in range(ss) for b in range(ss)]
    for ou, ov in tqdm(offsets, desc=desc or "cube texel average", disable=None, leave=False):
        u = (base + ou) / n * 2.0 - 1.0
        v = (base + ov) / n * 2.0 - 1.0
        vv, uu = np.meshgrid(v, u, indexing="ij")
        d = _cube.face_uv_to_direction(faces, uu[None], vv[None])
        r2 = 1.0 + uu * uu + vv * vv
        d /= np.sqrt(r2)[None, ..., None]
        wgt = (r2 ** -1.5)[None, ..., None]
        val = np.asarray(fn(d), dtype=np.float64)
        if val.ndim != 4 or val.shape[:3] != (6, n, n):
            raise ValueError(f"fn must return shape (6, {n}, {n}, C), got {val.shape}")
        acc = val * wgt if acc is None else acc + val * wgt
        wsum = wsum + wgt
    assert acc is not None
    return acc / wsum


def latlong_to_cube(img: NDArray, n: int, supersample: int | None = None) -> NDArray[np.float32]:
    """Resample a lat-long map ``(H, W, C)`` to a cube ``(6, n, n, C)`` float32 (texel averages).

    Each cube texel is the solid-angle-weighted mean of ``supersample``^2 bilinear lookups
    (:func:`cube_texel_average`).  The default picks ``ceil(W / (4 n))`` clamped to [2, 16], so
    that a texel gets at least about one lookup per lat-long pixel at the equator.
    """
    a = _check_image(img)
    n = _cube._check_size(n)
    if supersample is None:
        supersample = int(min(16, max(2, math.ceil(a.shape[1] / (4 * n)))))
    out = cube_texel_average(lambda d: sample_latlong(a, d), n, supersample, desc="lat-long -> cube")
    return out.astype(np.float32)


def cube_to_latlong(cube: NDArray, h: int, w: int) -> NDArray[np.float32]:
    """Resample a cube ``(6, N, N, C)`` to an ``h`` x ``w`` lat-long map ``(h, w, C)`` float32.

    Each lat-long texel center is looked up bilinearly *within* the cube face that contains it,
    clamped to the face's edge texels (not seamless across faces: within half a texel of a face
    edge the edge texel's value dominates).
    """
    a = _cube.check_cube(cube).astype(np.float64, copy=False)
    h, w = _check_hw(h, w)
    n = a.shape[1]
    d = latlong_directions(h, w)
    face, s, t = _cube.direction_to_face_st(d)
    x = np.clip(s * n - 0.5, 0.0, n - 1.0)
    y = np.clip(t * n - 0.5, 0.0, n - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.int64), n - 1)
    y0 = np.minimum(np.floor(y).astype(np.int64), n - 1)
    x1 = np.minimum(x0 + 1, n - 1)
    y1 = np.minimum(y0 + 1, n - 1)
    fx = (x - x0)[..., None]
    fy = (y - y0)[..., None]
    top = a[face, y0, x0] * (1.0 - fx) + a[face, y0, x1] * fx
    bot = a[face, y1, x0] * (1.0 - fx) + a[face, y1, x1] * fx
    return (top * (1.0 - fy) + bot * fy).astype(np.float32)


def read_latlong(path: str | os.PathLike[str], sanitize: bool = False) -> tuple[NDArray[np.float32], int]:
    """Read a lat-long HDR image (EXR, HDR, anything OpenImageIO reads) as ``(H, W, 3)`` float32.

    Returns ``(image, bad_count)``.  The first three channels are used (R, G, B in file order).
    The image must be 2:1 (``W == 2 H``).  Texels with a NaN, an Inf or a negative value in R, G
    or B are *bad*: by default the file is rejected (``ValueError`` naming the count and the first
    bad pixel as ``(x, y)``); with ``sanitize=True`` those channel values are replaced by 0 and the
    number of bad texels is returned.  A missing file raises ``FileNotFoundError``; an unreadable
    one ``ValueError``; both name the path.
    """
    import OpenImageIO as oiio

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"lat-long sky file not found: {p}")
    inp = oiio.ImageInput.open(str(p))
    if inp is None:
        raise ValueError(f"cannot read lat-long sky file {p}: {oiio.geterror() or 'unknown format'}")
    try:
        spec = inp.spec()
        wd, ht, nch = spec.width, spec.height, spec.nchannels
        if nch < 3:
            raise ValueError(f"lat-long sky file {p} has {nch} channel(s); need at least 3 (RGB)")
        if wd != 2 * ht:
            raise ValueError(f"lat-long sky file {p} is {wd}x{ht}; a lat-long map must be 2:1 (width = 2 * height)")
        data = inp.read_image(0, 0, 0, 3, "float")
        if data is None or inp.has_error:
            raise ValueError(f"cannot read pixels of lat-long sky file {p}: {inp.geterror()}")
    finally:
        inp.close()
    img = np.array(data, dtype=np.float32).reshape(ht, wd, 3)
    bad_ch = ~np.isfinite(img) | (img < 0)
    bad = np.any(bad_ch, axis=-1)
    count = int(bad.sum())
    if count:
        y, x = (int(i[0]) for i in np.nonzero(bad))
        nonfinite = int(np.sum(np.any(~np.isfinite(img), axis=-1)))
        if not sanitize:
            raise ValueError(
                f"lat-long sky file {p} has {count} bad texel(s) ({nonfinite} with NaN/Inf, the rest negative); "
                f"first at pixel (x={x}, y={y}) = {img[y, x].tolist()}; fix the file or load it with sanitize=True "
                "(replaces them with 0)")
        img[bad_ch] = 0.0
    return img, count


def load_latlong(path: str | os.PathLike[str], sanitize: bool = False) -> NDArray[np.float32]:
    """:func:`read_latlong` without the count: ``(H, W, 3)`` float32, linear RGB."""
    return read_latlong(path, sanitize=sanitize)[0]
