"""Float textures in KTX 2.0 files: cube maps and cube-map arrays with mip chains, and 2D texture
arrays of one level (the WebGL2 face atlases), through the one container writer
:mod:`envcap.formats.ktx2_container` (header, DFD, key/value data, alignment; ``docs/formats.md``).

Formats (:data:`FORMATS`): ``"rgba16f"`` = ``VK_FORMAT_R16G16B16A16_SFLOAT`` (97), ``"rgba32f"`` =
``VK_FORMAT_R32G32B32A32_SFLOAT`` (109), and the one-channel ``"r16f"`` = ``VK_FORMAT_R16_SFLOAT``
(76) and ``"r32f"`` = ``VK_FORMAT_R32_SFLOAT`` (100).  Level ``k`` of a cube has face size
``max(1, N >> k)``; face images are stored as in envcap cubes (``[face, row = t, column = s]``, GL
face order), which is what ``KTXorientation = "rd"`` states (s to the right, t down: row 0 first).
This module converts and checks the values (finite; half floats within +-65504 or clamped) and
streams them one level at a time.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, BinaryIO, Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.formats.ktx2_container import (
    R16_SFLOAT,
    R16G16B16A16_SFLOAT,
    R32_SFLOAT,
    R32G32B32A32_SFLOAT,
    Ktx2Shape,
    LevelWriter,
    VkFormat,
    read_ktx2_file,
    write_ktx2_file,
)

FORMATS: dict[str, VkFormat] = {"rgba16f": R16G16B16A16_SFLOAT, "rgba32f": R32G32B32A32_SFLOAT,
                                "r16f": R16_SFLOAT, "r32f": R32_SFLOAT}
"""Format name -> its vkFormat (:class:`envcap.formats.ktx2_container.VkFormat`: value, component
type, components: 4 = RGBA, 1 = R)."""

HALF_MAX = float(np.finfo(np.float16).max)
"""Largest finite half-float value (65504)."""

_BLOCK = 1 << 22
"""Values converted and written at once by :func:`float_levels` (16 MiB of float32)."""


def _format(fmt: str) -> VkFormat:
    if fmt not in FORMATS:
        raise ValueError(f"unknown KTX2 format {fmt!r}; expected one of {sorted(FORMATS)}")
    return FORMATS[fmt]


def _refuse(a: NDArray, fmt: str, clamp: bool, what: str) -> None:
    """Raise for the values of ``a`` that ``fmt`` cannot hold, naming their count in all of ``a``."""
    finite = np.isfinite(a)
    if not np.all(finite):
        bad = int(a.size - np.count_nonzero(finite))
        raise ValueError(f"{what}: {bad} value(s) are NaN or Inf; KTX2 probe data must be finite")
    if FORMATS[fmt].component.itemsize == 2:
        n_over = int(np.count_nonzero(np.abs(a) > HALF_MAX))
        if n_over and not clamp:
            raise ValueError(
                f"{what}: {n_over} value(s) exceed the half-float maximum {HALF_MAX:g} "
                f"(largest magnitude {float(np.max(np.abs(a))):g}); use fmt='rgba32f' or clamp=True"
            )
    else:
        with np.errstate(over="ignore"):
            if not np.all(np.isfinite(a.astype(np.float32))):   # float64 beyond float32 range
                raise ValueError(f"{what}: values overflow {fmt}")


def float_levels(levels: Sequence[NDArray], fmt: str, *, clamp: bool = False) -> LevelWriter:
    """The container's level writer of float arrays (:data:`envcap.formats.ktx2_container.LevelWriter`):
    level ``k`` converted to ``fmt``'s little-endian components in blocks of :data:`_BLOCK` values
    and appended.  A level that holds NaN/Inf, or (half formats) magnitudes above 65504 without
    ``clamp``, is refused with a ``ValueError`` counting them in the whole level, before any of
    it is written; with ``clamp`` those are clamped to +-65504, never Inf."""
    comp = _format(fmt).component
    half = comp.itemsize == 2
    limit = HALF_MAX if half else float(np.finfo(np.float32).max)

    def write(f: BinaryIO, k: int) -> None:
        a = np.asarray(levels[k])
        flat = np.ascontiguousarray(a).reshape(-1)
        blocks = [flat[i:i + _BLOCK] for i in range(0, flat.size, _BLOCK)]
        for b in blocks:
            if not np.isfinite(b).all() or ((not clamp or not half) and np.abs(b).max(initial=0.0) > limit):
                _refuse(a, fmt, clamp, f"level {k}")
        for b in blocks:
            if clamp and half:
                b = np.clip(b, -HALF_MAX, HALF_MAX)
            f.write(memoryview(b.astype(comp)).cast("B"))
    return write


def write_ktx2(
    path: str | os.PathLike[str],
    levels: Sequence[NDArray],
    *,
    layered: bool,
    fmt: str = "rgba16f",
    premultiplied: bool = False,
    clamp: bool = False,
) -> Path:
    """Write a float cube map (or cube-map array) with its mip chain as a KTX 2.0 file, atomically.

    ``levels[k]`` has shape ``(L, 6, N_k, N_k, C)`` when ``layered`` (cube-map array,
    ``layerCount = L``) or ``(6, N_k, N_k, C)`` (plain cube map, ``layerCount = 0``), with
    ``N_k = max(1, N_0 >> k)``; arrays are ``[layer, face (GL order), row = t, column = s,
    channel]``.  ``fmt`` is ``"rgba16f"`` or ``"rgba32f"`` (``C = 4``, RGBA) or ``"r16f"`` or
    ``"r32f"`` (``C = 1``, R).  Values must be finite; for the half formats values beyond
    +-65504 raise ``ValueError`` unless ``clamp=True``.  ``premultiplied`` sets the DFD's
    alpha-premultiplied flag (RGBA only).  Key/value data: ``KTXorientation`` and ``KTXwriter``
    only (:mod:`envcap.formats.ktx2_container`).  Returns the path.

    Streamed: the header, level index, DFD and key/values come from the shapes, then each level
    is converted and written on its own (smallest first, as the file stores them), so the
    converted copy held at once is one level, never the whole file.
    """
    vk = _format(fmt)
    if not isinstance(levels, (list, tuple)) or len(levels) == 0:
        raise ValueError("levels must be a non-empty list of arrays")
    nch = vk.components
    if premultiplied and nch != 4:
        raise ValueError(f"premultiplied needs an alpha channel; {fmt!r} has none")
    n0 = layers = 0
    for k, lev in enumerate(levels):
        a = np.asarray(lev)
        if a.ndim != (5 if layered else 4) or a.shape[-4] != 6 or a.shape[-1] != nch or a.shape[-3] != a.shape[-2]:
            want = f"(L, 6, N, N, {nch})" if layered else f"(6, N, N, {nch})"
            raise ValueError(f"level {k} must have shape {want}, got {a.shape}")
        if k == 0:
            n0, layers = a.shape[-2], (a.shape[0] if layered else 0)
            if n0 < 1 or (layered and layers < 1):
                raise ValueError(f"level 0 has an empty shape {a.shape}")
            if len(levels) > n0.bit_length():
                raise ValueError(f"{len(levels)} levels given, but a {n0}-texel cube has at most {n0.bit_length()}")
        nk = max(1, n0 >> k)
        if a.shape[-2] != nk or (layered and a.shape[0] != layers):
            want = ((layers,) if layered else ()) + (6, nk, nk, nch)
            raise ValueError(f"level {k} must have shape {want}, got {a.shape}")
        if not np.issubdtype(a.dtype, np.floating):
            raise ValueError(f"level {k}: expected a floating-point array, got dtype {a.dtype}")
    shape = Ktx2Shape(vk, n0, n0, layers, 6, len(levels))
    return write_ktx2_file(path, shape, float_levels(levels, fmt, clamp=clamp), premultiplied=premultiplied)


def write_ktx2_array(path: str | os.PathLike[str], image: NDArray, *, fmt: str = "rgba16f",
                     premultiplied: bool = False) -> Path:
    """Write ``image`` ``(L, H, W, 4)`` (float, finite; ``rgba16f`` values within +-65504) as a
    KTX2 2D texture array of one level (``faceCount = 1``, ``layerCount = L``), atomically; return
    the path.  The level holds the layers in order, each ``H`` rows (row 0 first) of ``W`` RGBA
    texels: the C order of ``image``, uploadable as-is with ``texImage3D(TEXTURE_2D_ARRAY, 0,
    RGBA16F, W, H, L, 0, RGBA, HALF_FLOAT, data)``.  ``premultiplied`` sets the DFD's flag."""
    if fmt not in ("rgba16f", "rgba32f"):
        raise ValueError(f"KTX2 texture arrays are RGBA: fmt must be 'rgba16f' or 'rgba32f', got {fmt!r}")
    a = np.asarray(image)
    if a.ndim != 4 or a.shape[-1] != 4 or min(a.shape[:3]) < 1:
        raise ValueError(f"a KTX2 texture array must have shape (L, H, W, 4) with L, H, W >= 1, got {a.shape}")
    if not np.issubdtype(a.dtype, np.floating):
        raise ValueError(f"KTX2 texture array: expected a floating-point array, got dtype {a.dtype}")
    layers, h, w = a.shape[:3]
    shape = Ktx2Shape(FORMATS[fmt], w, h, layers, 1, 1)
    return write_ktx2_file(path, shape, float_levels([a], fmt), premultiplied=premultiplied)


def read_ktx2(path: str | os.PathLike[str]) -> tuple[list[NDArray[np.float32]], dict[str, Any]]:
    """Read a KTX 2.0 float cube map / cube-map array written by :func:`write_ktx2` (or any writer
    of the same subset), validating every header and DFD field
    (:func:`envcap.formats.ktx2_container.read_ktx2_file`).

    Returns ``(levels, info)``: ``levels[k]`` float32 of shape ``(L, 6, N_k, N_k, C)`` for a
    cube-map array or ``(6, N_k, N_k, C)`` for a plain cube map (``C``: 4, or 1 for ``r16f`` /
    ``r32f``); ``info`` holds ``fmt``, ``vk_format``, ``size``, ``layers`` (0 for a plain cube),
    ``level_count``, ``layered``, ``premultiplied`` and ``kv`` (dict str -> str: the file's
    key/value entries; a file written before issue 19 may hold a custom key, e.g. ``envcap.lobes`` in a
    ``chain.ktx2``: it is read like any other and nothing depends on it).  Raises
    ``FileNotFoundError`` for a missing file and ``ValueError`` naming the problem for a
    truncated or corrupt one.
    """
    got = read_ktx2_file(path, formats=FORMATS.values(), faces=6)
    s = got.shape
    fmt = next(name for name, vk in FORMATS.items() if vk == s.fmt)
    levels = [(a if s.layers else a[0]).astype(np.float32) for a in got.levels]
    info = {
        "fmt": fmt, "vk_format": s.fmt.value, "size": s.width, "layers": s.layers, "level_count": s.levels,
        "layered": s.layers > 0, "premultiplied": got.premultiplied, "kv": got.kv,
    }
    return levels, info
