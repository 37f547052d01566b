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

Azimuth in envcap (``envcap.sky``) is the longitude: measured from +Z towards +X.
"""

from __future__ import annotations

import math
import os
from typing import Callable

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from envcap.core import budget
from envcap.core import cube as _cube
from envcap.core.checks import finite_directions, positive_int
from envcap.core.image_read import read_rgb_radiance

__all__ = [
    "latlong_directions",
    "direction_to_latlong",
    "direction_to_latlong_xy",
    "latlong_solid_angles",
    "sample_latlong",
    "cube_texel_average",
    "latlong_box_average",
    "latlong_to_cube",
    "cube_to_latlong",
    "read_latlong",
    "load_latlong",
]


BOX_MIN_PIXELS_PER_TEXEL = 4
""":func:`latlong_to_cube` averages the pixels inside each cube texel (:func:`latlong_box_average`)
when the image has at least this many pixels per cube texel along the equator
(``W >= 4 n * BOX_MIN_PIXELS_PER_TEXEL``); below, it supersamples bilinear lookups.  From 4 on,
every texel (even at the cube corners, the smallest) holds several pixel centers, and the box
average keeps a small bright source's energy within a few percent where ``ss^2`` bilinear lookups
missed or doubled it (``docs/sky.md``, "Lat-long to cube")."""

TILE_TEXELS = 1 << 16
"""Cube texels per tile of :func:`cube_texel_average` (bounds its temporaries to some tens of MB)."""

BAND_PIXELS = 1 << 20
"""Lat-long pixels per band of rows in :func:`latlong_box_average` (at least the cube's texel count)."""

INDEX_CHUNK_PIXELS = 1 << 16
"""Pixels whose texel index :func:`latlong_box_average` computes at once (fits a CPU cache: 4x faster
than whole bands)."""

# Estimated float64 temporaries, for the memory budget only: per tile texel and channel
# (directions, weights, the four bilinear neighbours, sums), per band pixel (texel index, weight,
# weighted value, one channel) and per index-chunk pixel (directions, face coordinates, masks).
_FLOATS_PER_TILE_TEXEL = 24
_FLOATS_PER_BAND_PIXEL = 4
_FLOATS_PER_CHUNK_PIXEL = 24
_SIZE_OPTION = "the cube face size (prefilter --size, capture --resolution)"


def _check_hw(h: int, w: int) -> tuple[int, int]:
    return positive_int(h, "lat-long height"), positive_int(w, "lat-long width")


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


def direction_to_latlong(d: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Latitude and longitude (radians) of directions ``d`` of shape ``(..., 3)`` (any length > 0).

    ``lat`` in [-pi/2, pi/2], ``lon = atan2(x, z)`` in [-pi, pi] (0 at the poles).  Computed with
    ``atan2`` so it is accurate near the poles.  Zero or non-finite directions raise ``ValueError``.
    """
    d = finite_directions(d)
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
    return np.broadcast_to(_row_solid_angles(h, w)[:, None], (h, w)).copy()


def _row_solid_angles(h: int, w: int) -> NDArray[np.float64]:
    # Solid angle of one pixel of each row, shape (h,): see latlong_solid_angles.
    half = 0.5 * np.pi / h
    mid = 0.5 * np.pi - (np.arange(h, dtype=np.float64) + 0.5) * np.pi / h
    return (2.0 * np.pi / w) * 2.0 * np.cos(mid) * np.sin(half)


def _check_image(img: NDArray, name: str = "lat-long image") -> NDArray:
    a = np.asarray(img)
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 1 or a.shape[2] < 1:
        raise ValueError(f"{name} must have shape (H, W, C), got {a.shape}")
    return a


def sample_latlong(img: NDArray, d: NDArray) -> NDArray[np.float64]:
    """Bilinear lookup of a lat-long map ``img`` (``(H, W, C)``) at directions ``d`` (``(..., 3)``).

    Longitude wraps around (the left and right edges are neighbours); latitude clamps to the
    first/last row's center (above the top row's center the top row's value is returned).
    Returns ``(..., C)`` float64; only the four neighbours of each lookup are converted to
    float64, never the whole image.
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
    fx = fx[..., None]
    fy = fy[..., None]

    def at(yi: NDArray, xi: NDArray) -> NDArray[np.float64]:
        return a[yi, xi].astype(np.float64, copy=False)

    top = at(y0, x0) * (1.0 - fx) + at(y0, x1) * fx
    bot = at(y1, x0) * (1.0 - fx) + at(y1, x1) * fx
    return top * (1.0 - fy) + bot * fy


def _texel_average_into(fn: Callable[[NDArray[np.float64]], NDArray], n: int, ss: int, dtype: type,
                        desc: str, tile_texels: int) -> NDArray:
    # Tiles are bands of consecutive rows of the (6 n, n) stack of face rows; every texel gets the
    # same float64 operations in the same order whatever the tiling (bit-identical results).
    rows_per_tile = max(1, int(tile_texels) // n)
    offsets = [((a + 0.5) / ss, (b + 0.5) / ss) for a in range(ss) for b in range(ss)]
    u_base = np.arange(n, dtype=np.float64)
    out: NDArray | None = None
    for r0 in tqdm(range(0, 6 * n, rows_per_tile), desc=desc, disable=None, leave=False):
        face_row = np.arange(r0, min(r0 + rows_per_tile, 6 * n))
        faces = (face_row // n)[:, None]
        v_base = (face_row % n).astype(np.float64)
        acc = None
        wsum = np.zeros((face_row.size, n, 1), dtype=np.float64)
        for ou, ov in offsets:
            u = (u_base + ou) / n * 2.0 - 1.0
            v = (v_base + ov) / n * 2.0 - 1.0
            vv, uu = np.meshgrid(v, u, indexing="ij")
            d = _cube.face_uv_to_direction(faces, uu, vv)
            r2 = 1.0 + uu * uu + vv * vv
            d /= np.sqrt(r2)[..., None]
            wgt = (r2 ** -1.5)[..., None]
            val = np.asarray(fn(d), dtype=np.float64)
            if val.ndim != 3 or val.shape[:2] != d.shape[:2]:
                raise ValueError(f"fn must map directions (..., 3) to values (..., C), got {d.shape} -> {val.shape}")
            acc = val * wgt if acc is None else acc + val * wgt
            wsum = wsum + wgt
        assert acc is not None
        if out is None:
            c = acc.shape[-1]
            budget.check_bytes(f"cube of 6x{n}x{n} texels x {c} channel(s)", 6 * n * n * c * np.dtype(dtype).itemsize,
                               option=_SIZE_OPTION)
            out = np.empty((6 * n, n, c), dtype=dtype)
        out[face_row] = acc / wsum
    assert out is not None
    return out.reshape(6, n, n, -1)


def cube_texel_average(fn: Callable[[NDArray[np.float64]], NDArray], n: int, supersample: int = 4,
                       desc: str | None = None, tile_texels: int = TILE_TEXELS) -> NDArray[np.float64]:
    """Solid-angle-weighted texel averages of a function of direction over an ``n``-texel cube.

    ``fn`` maps unit directions ``(..., 3)`` float64 to values ``(..., C)``; it is called on tiles
    of at most about ``tile_texels`` texels (``(rows, n, 3)``), so memory stays bounded whatever
    ``n``.  Each texel is split into ``supersample`` x ``supersample`` equal sub-squares in face
    coordinates; each sub-sample is weighted by the solid-angle density ``(1 + u^2 + v^2)^(-3/2)``
    and the weights are normalised per texel.  Returns ``(6, n, n, C)`` float64 (envcap cube
    layout).  A tqdm bar shows progress.
    """
    n = positive_int(n, "cube face size")
    ss = positive_int(supersample, "supersample")
    return _texel_average_into(fn, n, ss, np.float64, desc or "cube texel average", tile_texels)


def _texel_index(x: NDArray[np.float64], y: NDArray[np.float64], z: NDArray[np.float64], n: int) -> NDArray[np.int64]:
    # Flat texel index (face * n + row) * n + column of directions (x, y, z) (broadcastable, not
    # normalised, never zero): the same face choice and float64 operations as
    # envcap.core.cube.direction_to_texel, with fewer temporaries (it is the box average's hot loop).
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    xmaj = (ax >= ay) & (ax >= az)
    ymaj = ~xmaj & (ay >= az)
    ma = np.where(xmaj, ax, np.where(ymaj, ay, az))
    sc = np.where(xmaj, np.where(x >= 0, -z, z), np.where(ymaj | (z >= 0), x, -x))
    tc = np.where(ymaj, np.where(y >= 0, z, -z), -y)
    face = np.where(xmaj, x < 0, np.where(ymaj, 2 + (y < 0), 4 + (z < 0)))
    col = np.clip(np.floor((sc / ma + 1.0) * 0.5 * n), 0, n - 1).astype(np.int64)
    row = np.clip(np.floor((tc / ma + 1.0) * 0.5 * n), 0, n - 1).astype(np.int64)
    return (face * n + row) * n + col


def latlong_box_average(img: NDArray, n: int, band_pixels: int = BAND_PIXELS) -> NDArray[np.float32]:
    """Area-weighted reduction of a lat-long map ``(H, W, C)`` to a cube ``(6, n, n, C)`` float32.

    Each cube texel is the mean of the pixels whose centers fall in it, weighted by each pixel's
    exact solid angle (:func:`latlong_solid_angles`) and accumulated in float64: the right
    method when the image is finer than the cube (many pixels per texel); a pixel straddling a
    texel border counts whole for the texel holding its center.  Rows are processed in bands of
    about ``max(band_pixels, 6 n^2)`` pixels, so memory is the image plus a band and the float64
    sums, both bounded by the cube's size.  A texel that no
    pixel center falls in (only when the image is coarser than the cube) gets the bilinear
    lookup (:func:`sample_latlong`) at its center.
    """
    a = _check_image(img)
    n = positive_int(n, "cube face size")
    h, w, c = a.shape
    lon = -2.0 * np.pi * ((np.arange(w, dtype=np.float64) + 0.5) / w - 0.5)
    lat = -np.pi * ((np.arange(h, dtype=np.float64) + 0.5) / h - 0.5)
    sin_lon, cos_lon = np.sin(lon)[None, :], np.cos(lon)[None, :]
    omega = _row_solid_angles(h, w)
    texels = 6 * n * n
    sums = np.zeros((c, texels), dtype=np.float64)
    wsum = np.zeros(texels, dtype=np.float64)
    # Texel indices are computed in chunks small enough for the CPU cache; the bincounts run once a
    # band, and a band holds at least as many pixels as the cube has texels, so that zeroing and
    # adding the per-band counts costs no more than the band's own work.
    band_rows = max(1, max(int(band_pixels), texels) // w)
    chunk_rows = max(1, min(band_rows, INDEX_CHUNK_PIXELS // w))
    for y0 in tqdm(range(0, h, band_rows), desc="lat-long -> cube (box)", disable=None, leave=False):
        y1 = min(h, y0 + band_rows)
        idx = np.empty((y1 - y0, w), dtype=np.int64)
        for c0 in range(y0, y1, chunk_rows):
            c1 = min(y1, c0 + chunk_rows)
            cl = np.cos(lat[c0:c1])[:, None]
            idx[c0 - y0:c1 - y0] = _texel_index(sin_lon * cl, np.sin(lat[c0:c1])[:, None], cos_lon * cl, n)
        idx = idx.ravel()
        wgt = np.repeat(omega[y0:y1], w)
        wsum += np.bincount(idx, weights=wgt, minlength=texels)
        for k in range(c):
            sums[k] += np.bincount(idx, weights=a[y0:y1, :, k].ravel() * wgt, minlength=texels)
    empty = wsum == 0
    wsum[empty] = 1.0
    out = (sums / wsum).T.reshape(6, n, n, c).astype(np.float32)
    if np.any(empty):
        f, t, s = np.unravel_index(np.flatnonzero(empty), (6, n, n))
        d = _cube.face_uv_to_direction(f, (s + 0.5) / n * 2.0 - 1.0, (t + 0.5) / n * 2.0 - 1.0)
        out[f, t, s] = sample_latlong(a, d)
    return out


def latlong_to_cube(img: NDArray, n: int, supersample: int | None = None) -> NDArray[np.float32]:
    """Resample a lat-long map ``(H, W, C)`` to a cube ``(6, n, n, C)`` float32 (texel averages).

    With ``supersample=None`` (default) an image finer than the cube, with at least
    :data:`BOX_MIN_PIXELS_PER_TEXEL` pixels per texel along the equator (``W >= 16 n``), is
    reduced by :func:`latlong_box_average`: every pixel counts once, in time proportional to the
    image.  Otherwise each cube texel is the solid-angle-weighted mean of ``supersample``^2
    bilinear lookups (:func:`cube_texel_average`), by default ``ceil(W / (4 n))`` clamped to
    [2, 16]: about one lookup per lat-long pixel at the equator.  Memory is the output plus a
    bounded tile or band; it is checked against :func:`envcap.core.budget.check_bytes` first.
    """
    a = _check_image(img)
    n = positive_int(n, "cube face size")
    h, w, c = a.shape
    box = supersample is None and w >= 4 * n * BOX_MIN_PIXELS_PER_TEXEL
    cube_bytes = 6 * n * n * c * 4 + (6 * n * n * (c + 1) * 8 if box else 0)
    if box:
        band = min(h * w, max(BAND_PIXELS, 6 * n * n) + w)
        temp_bytes = 8 * (_FLOATS_PER_BAND_PIXEL * band + 6 * n * n + _FLOATS_PER_CHUNK_PIXEL * INDEX_CHUNK_PIXELS)
    else:
        temp_bytes = 8 * _FLOATS_PER_TILE_TEXEL * max(n, min(TILE_TEXELS, 6 * n * n)) * (1 + c)
    budget.check_bytes(f"lat-long {w}x{h} to a cube of 6x{n}x{n} texels", cube_bytes + temp_bytes,
                       option=_SIZE_OPTION)
    if box:
        return latlong_box_average(a, n)
    if supersample is None:
        supersample = int(min(16, max(2, math.ceil(w / (4 * n)))))
    ss = positive_int(supersample, "supersample")
    return _texel_average_into(lambda d: sample_latlong(a, d), n, ss, np.float32, "lat-long -> cube", TILE_TEXELS)


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
    """Read a lat-long image (EXR, HDR, PNG, anything OpenImageIO reads) as ``(H, W, 3)`` float32.

    Returns ``(image, bad_count)``; the reading rules are :func:`envcap.core.image_read.read_rgb_radiance`'s:
    the first three channels are R, G, B; an LDR (integer) file is decoded from sRGB to linear
    with a warning on stderr; texels with a NaN, an Inf or a negative value in R, G or B are
    *bad*: by default the file is rejected (``ValueError`` naming the count and the first bad
    pixel as ``(x, y)``); with ``sanitize=True`` those channel values are replaced by 0 and the
    number of bad texels is returned.  The image must be 2:1 (``W == 2 H``).  A missing file
    raises ``FileNotFoundError``; an unreadable or truncated one ``ValueError``; an image too
    large for memory :class:`envcap.core.budget.BudgetError`; all name the path, in one line.
    """

    def two_to_one(w: int, h: int) -> str | None:
        return None if w == 2 * h else "a lat-long map must be 2:1 (width = 2 * height)"

    return read_rgb_radiance(path, what="lat-long sky file", sanitize=sanitize, shape_check=two_to_one)


def load_latlong(path: str | os.PathLike[str], sanitize: bool = False) -> NDArray[np.float32]:
    """:func:`read_latlong` without the count: ``(H, W, 3)`` float32, linear RGB."""
    return read_latlong(path, sanitize=sanitize)[0]
