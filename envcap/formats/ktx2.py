"""KTX 2.0 files for float cube maps and cube-map arrays with mip chains.

Written from the Khronos KTX 2.0 specification (https://registry.khronos.org/KTX/specs/2.0/)
and the Khronos Data Format specification 1.3; see ``docs/formats.md`` for the layout.

Supported: ``VK_FORMAT_R16G16B16A16_SFLOAT`` (97, ``"rgba16f"``) and
``VK_FORMAT_R32G32B32A32_SFLOAT`` (109, ``"rgba32f"``), and the one-channel
``VK_FORMAT_R16_SFLOAT`` (76, ``"r16f"``) and ``VK_FORMAT_R32_SFLOAT`` (100, ``"r32f"``);
``faceCount = 6``, ``pixelDepth = 0``, no supercompression.  Level ``k`` of a cube has face
size ``max(1, N >> k)``; face images are stored as in envcap cubes (``[face, row = t, column =
s]``, GL face order), which is what ``KTXorientation = "rd"`` states (s to the right, t down:
row 0 first).
"""

from __future__ import annotations

import math
import os
import struct
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap import __version__
from envcap.outputs import atomic_output_file

IDENTIFIER = b"\xabKTX 20\xbb\r\n\x1a\n"
"""The 12-byte KTX 2.0 file identifier."""

VK_FORMAT_R16G16B16A16_SFLOAT = 97
VK_FORMAT_R32G32B32A32_SFLOAT = 109
VK_FORMAT_R16_SFLOAT = 76
VK_FORMAT_R32_SFLOAT = 100

FORMATS: dict[str, tuple[int, type]] = {
    "rgba16f": (VK_FORMAT_R16G16B16A16_SFLOAT, np.float16),
    "rgba32f": (VK_FORMAT_R32G32B32A32_SFLOAT, np.float32),
    "r16f": (VK_FORMAT_R16_SFLOAT, np.float16),
    "r32f": (VK_FORMAT_R32_SFLOAT, np.float32),
}
"""Format name -> (vkFormat, numpy component dtype)."""

CHANNELS: dict[str, int] = {"rgba16f": 4, "rgba32f": 4, "r16f": 1, "r32f": 1}
"""Format name -> components per texel (RGBA, or R alone: one DFD sample, channel id 0)."""

HALF_MAX = float(np.finfo(np.float16).max)
"""Largest finite half-float value (65504)."""

# Khronos Data Format constants (khr_df.h).
KHR_DF_VENDORID_KHRONOS = 0
KHR_DF_KHR_DESCRIPTORTYPE_BASICFORMAT = 0
KHR_DF_VERSIONNUMBER_1_3 = 2
KHR_DF_MODEL_RGBSDA = 1
KHR_DF_PRIMARIES_BT709 = 1
KHR_DF_TRANSFER_LINEAR = 1
KHR_DF_FLAG_ALPHA_PREMULTIPLIED = 1
KHR_DF_SAMPLE_DATATYPE_FLOAT = 0x80
KHR_DF_SAMPLE_DATATYPE_SIGNED = 0x40
CHANNEL_IDS = (0, 1, 2, 15)  # R, G, B, A in the RGBSDA model
FLOAT_LOWER = 0xBF800000  # -1.0f: sampleLower of a signed float sample
FLOAT_UPPER = 0x3F800000  # +1.0f: sampleUpper of a signed float sample

_HEADER = struct.Struct("<12s9I4I2Q")  # identifier, 9 uint32 fields, dfd/kvd offsets+lengths, sgd (uint64)
_LEVEL = struct.Struct("<3Q")


def _align(x: int, a: int) -> int:
    return (x + a - 1) // a * a


def _dfd(fmt: str, premultiplied: bool) -> bytes:
    """Basic Data Format Descriptor (with its leading dfdTotalSize) for an RGBA or R float format."""
    comp = FORMATS[fmt][1]
    bits = np.dtype(comp).itemsize * 8
    nch = CHANNELS[fmt]
    block_size = 24 + 16 * nch
    words = [
        (KHR_DF_KHR_DESCRIPTORTYPE_BASICFORMAT << 17) | KHR_DF_VENDORID_KHRONOS,
        (block_size << 16) | KHR_DF_VERSIONNUMBER_1_3,
        KHR_DF_MODEL_RGBSDA
        | (KHR_DF_PRIMARIES_BT709 << 8)
        | (KHR_DF_TRANSFER_LINEAR << 16)
        | ((KHR_DF_FLAG_ALPHA_PREMULTIPLIED if premultiplied else 0) << 24),
        0,  # texelBlockDimension0..3 = 1x1x1x1 (stored minus one)
        nch * bits // 8,  # bytesPlane0 = texel size, bytesPlane1..3 = 0
        0,  # bytesPlane4..7
    ]
    for i, ch in enumerate(CHANNEL_IDS[:nch]):
        ctype = ch | KHR_DF_SAMPLE_DATATYPE_FLOAT | KHR_DF_SAMPLE_DATATYPE_SIGNED
        words += [(i * bits) | ((bits - 1) << 16) | (ctype << 24), 0, FLOAT_LOWER, FLOAT_UPPER]
    body = struct.pack(f"<{len(words)}I", *words)
    return struct.pack("<I", 4 + len(body)) + body


def _kvd(kv: dict[str, str]) -> bytes:
    """Key/value data: entries sorted by key bytes, each value a NUL-terminated UTF-8 string."""
    out = bytearray()
    items = sorted(((k.encode("utf-8"), v.encode("utf-8")) for k, v in kv.items()), key=lambda kvp: kvp[0])
    for k, v in items:
        payload = k + b"\0" + v + b"\0"
        out += struct.pack("<I", len(payload)) + payload
        out += b"\0" * (_align(len(out), 4) - len(out))
    return bytes(out)


def _check_kv(kv: dict[str, str] | None) -> dict[str, str]:
    out = {"KTXorientation": "rd", "KTXwriter": f"envcap {__version__}"}
    for k, v in (kv or {}).items():
        if not isinstance(k, str) or not isinstance(v, str):
            raise ValueError(f"KTX2 key/value data must be str -> str, got {k!r}: {type(v).__name__}")
        if not k or "\0" in k or "\0" in v:
            raise ValueError(f"KTX2 key {k!r}: keys must be non-empty and keys/values must not contain NUL")
        if k in ("KTXorientation", "KTXwriter"):
            raise ValueError(f"KTX2 key {k!r} is set by the writer")
        out[k] = v
    return out


def _convert(a: NDArray, fmt: str, clamp: bool, what: str) -> NDArray:
    a = np.asarray(a)
    if not np.issubdtype(a.dtype, np.floating):
        raise ValueError(f"{what}: expected a floating-point array, got dtype {a.dtype}")
    finite = np.isfinite(a)
    if not np.all(finite):
        bad = int(a.size - np.count_nonzero(finite))
        raise ValueError(f"{what}: {bad} value(s) are NaN or Inf; KTX2 probe data must be finite")
    comp = FORMATS[fmt][1]
    if comp is np.float16:
        over = np.abs(a) > HALF_MAX
        n_over = int(np.count_nonzero(over))
        if n_over:
            if not clamp:
                raise ValueError(
                    f"{what}: {n_over} value(s) exceed the half-float maximum {HALF_MAX:g} "
                    f"(largest magnitude {float(np.max(np.abs(a))):g}); use fmt='rgba32f' or clamp=True"
                )
            a = np.clip(a, -HALF_MAX, HALF_MAX)
    out = a.astype(comp)
    if not np.all(np.isfinite(out)):  # float64 beyond float32 range, for instance
        raise ValueError(f"{what}: values overflow {fmt}")
    return out


_BLOCK = 1 << 22
"""Values converted and written at once by :func:`_write_level` (16 MiB of float32)."""


def _write_level(f: Any, a: NDArray, fmt: str, clamp: bool, what: str) -> None:
    """Convert ``a`` to ``fmt``'s little-endian components and append them to ``f``, in blocks of
    :data:`_BLOCK` values; a level that :func:`_convert` would refuse is refused with its message
    (the whole level checked) before anything of it is written."""
    comp = np.dtype(FORMATS[fmt][1]).newbyteorder("<")
    flat = np.ascontiguousarray(a).reshape(-1)
    blocks = [flat[i:i + _BLOCK] for i in range(0, flat.size, _BLOCK)]
    half = FORMATS[fmt][1] is np.float16
    limit = HALF_MAX if half else float(np.finfo(np.float32).max)
    for b in blocks:
        if not np.isfinite(b).all() or ((not clamp or not half) and np.abs(b).max(initial=0.0) > limit):
            out = _convert(a, fmt, clamp, what)  # raises, naming the counts of the whole level
            f.write(memoryview(np.ascontiguousarray(out, dtype=comp).reshape(-1)).cast("B"))  # (rounds into range)
            return
    for b in blocks:
        if clamp and half:
            b = np.clip(b, -HALF_MAX, HALF_MAX)
        f.write(memoryview(b.astype(comp)).cast("B"))


def write_ktx2(
    path: str | os.PathLike[str],
    levels: list[NDArray],
    *,
    layered: bool,
    fmt: str = "rgba16f",
    kv: dict[str, str] | None = None,
    premultiplied: bool = False,
    clamp: bool = False,
) -> Path:
    """Write a float cube map (or cube-map array) with its mip chain as a KTX 2.0 file, atomically.

    ``levels[k]`` has shape ``(L, 6, N_k, N_k, C)`` when ``layered`` (cube-map array,
    ``layerCount = L``) or ``(6, N_k, N_k, C)`` (plain cube map, ``layerCount = 0``), with
    ``N_k = max(1, N_0 >> k)``; arrays are ``[layer, face (GL order), row = t, column = s,
    channel]``.  ``fmt`` is ``"rgba16f"`` or ``"rgba32f"`` (``C = 4``, RGBA) or ``"r16f"`` or
    ``"r32f"`` (``C = 1``, R).  Values must be finite; for the half formats values beyond
    +-65504 raise ``ValueError`` unless ``clamp=True``.
    ``premultiplied`` sets the DFD's alpha-premultiplied flag (RGBA only).  ``kv`` adds key/value
    entries (str -> str) next to ``KTXorientation = "rd"`` and ``KTXwriter``.  Returns the path.

    Streamed: the header, level index, DFD and key/values are computed from the shapes, then
    each level is converted and written on its own (smallest first, as the file stores them), so
    the converted copy held at once is one level, never the whole file.  Bytes are those of the
    earlier in-memory writer (``tests/formats/test_ktx2_stream.py`` pins them).
    """
    if fmt not in FORMATS:
        raise ValueError(f"unknown KTX2 format {fmt!r}; expected one of {sorted(FORMATS)}")
    if not isinstance(levels, (list, tuple)) or len(levels) == 0:
        raise ValueError("levels must be a non-empty list of arrays")
    vk_format, comp = FORMATS[fmt]
    nch = CHANNELS[fmt]
    if premultiplied and nch != 4:
        raise ValueError(f"premultiplied needs an alpha channel; {fmt!r} has none")
    arrays: list[NDArray] = []  # the checked, unconverted levels
    n0 = layers = 0
    for k, lev in enumerate(levels):
        a = np.asarray(lev)
        exp_nd = 5 if layered else 4
        if a.ndim != exp_nd or a.shape[-4] != 6 or a.shape[-1] != nch or a.shape[-3] != a.shape[-2]:
            want = f"(L, 6, N, N, {nch})" if layered else f"(6, N, N, {nch})"
            raise ValueError(f"level {k} must have shape {want}, got {a.shape}")
        if k == 0:
            n0 = a.shape[-2]
            layers = a.shape[0] if layered else 0
            if n0 < 1 or (layered and layers < 1):
                raise ValueError(f"level 0 has an empty shape {a.shape}")
            max_levels = int(math.floor(math.log2(n0))) + 1
            if len(levels) > max_levels:
                raise ValueError(f"{len(levels)} levels given, but a {n0}-texel cube has at most {max_levels}")
        nk = max(1, n0 >> k)
        if a.shape[-2] != nk or (layered and a.shape[0] != layers):
            want = ((layers,) if layered else ()) + (6, nk, nk, nch)
            raise ValueError(f"level {k} must have shape {want}, got {a.shape}")
        if not np.issubdtype(a.dtype, np.floating):
            raise ValueError(f"level {k}: expected a floating-point array, got dtype {a.dtype}")
        arrays.append(a)
    kvd = _kvd(_check_kv(kv))
    dfd = _dfd(fmt, premultiplied)
    n_levels = len(arrays)
    texel = nch * np.dtype(comp).itemsize
    align = math.lcm(texel, 4)
    nbytes = [a.size * np.dtype(comp).itemsize for a in arrays]

    dfd_off = _HEADER.size + _LEVEL.size * n_levels
    kvd_off = dfd_off + len(dfd)
    pos = kvd_off + len(kvd)
    offsets = [0] * n_levels
    for k in reversed(range(n_levels)):  # smallest level first in the file
        pos = _align(pos, align)
        offsets[k] = pos
        pos += nbytes[k]
    header = _HEADER.pack(
        IDENTIFIER, vk_format, np.dtype(comp).itemsize, n0, n0, 0, layers, 6, n_levels, 0,
        dfd_off, len(dfd), kvd_off, len(kvd), 0, 0,
    )
    index = b"".join(_LEVEL.pack(offsets[k], nbytes[k], nbytes[k]) for k in range(n_levels))
    final = Path(path)
    with atomic_output_file(final) as tmp:
        with open(tmp, "wb") as f:
            f.write(header + index + dfd + kvd)
            for k in reversed(range(n_levels)):
                f.write(b"\0" * (offsets[k] - f.tell()))
                _write_level(f, arrays[k], fmt, clamp, f"level {k}")
    return final


def read_ktx2(path: str | os.PathLike[str]) -> tuple[list[NDArray[np.float32]], dict[str, Any]]:
    """Read a KTX 2.0 float cube map / cube-map array written by :func:`write_ktx2` (or any writer
    of the same subset), validating every header field.

    Returns ``(levels, info)``: ``levels[k]`` float32 of shape ``(L, 6, N_k, N_k, C)`` for a
    cube-map array or ``(6, N_k, N_k, C)`` for a plain cube map (``C``: 4, or 1 for ``r16f`` /
    ``r32f``); ``info`` holds ``fmt``, ``vk_format``, ``size``, ``layers`` (0 for a plain cube),
    ``level_count``, ``layered``, ``premultiplied`` and ``kv`` (dict str -> str).  Raises
    ``FileNotFoundError`` for a missing file and ``ValueError`` naming the problem for a truncated
    or corrupt one.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"KTX2 file not found: {p}")
    data = p.read_bytes()
    where = f"KTX2 file {p}"
    if len(data) < _HEADER.size:
        raise ValueError(f"{where}: truncated ({len(data)} bytes, header needs {_HEADER.size})")
    (ident, vk_format, type_size, width, height, depth, layers, faces, n_levels, scheme,
     dfd_off, dfd_len, kvd_off, kvd_len, sgd_off, sgd_len) = _HEADER.unpack_from(data, 0)
    if ident != IDENTIFIER:
        raise ValueError(f"{where}: not a KTX 2.0 file (bad identifier {ident!r})")
    fmts = {v[0]: name for name, v in FORMATS.items()}
    if vk_format not in fmts:
        raise ValueError(f"{where}: vkFormat {vk_format} not supported "
                         "(expected 97 RGBA16F, 109 RGBA32F, 76 R16F or 100 R32F)")
    fmt = fmts[vk_format]
    comp = np.dtype(FORMATS[fmt][1])
    nch = CHANNELS[fmt]
    if type_size != comp.itemsize:
        raise ValueError(f"{where}: typeSize {type_size} does not match {fmt} (expected {comp.itemsize})")
    if faces != 6:
        raise ValueError(f"{where}: faceCount {faces}, expected 6 (a cube map)")
    if width < 1 or width != height:
        raise ValueError(f"{where}: cube faces must be square and non-empty, got {width}x{height}")
    if depth != 0:
        raise ValueError(f"{where}: pixelDepth {depth}, expected 0 for a cube map")
    if scheme != 0:
        raise ValueError(f"{where}: supercompressionScheme {scheme} not supported (expected 0, none)")
    max_levels = int(math.floor(math.log2(width))) + 1
    if not 1 <= n_levels <= max_levels:
        raise ValueError(f"{where}: levelCount {n_levels} invalid for size {width} (1..{max_levels})")
    if sgd_off != 0 or sgd_len != 0:
        raise ValueError(f"{where}: unexpected supercompression global data")
    index_end = _HEADER.size + _LEVEL.size * n_levels
    if len(data) < index_end:
        raise ValueError(f"{where}: truncated in the level index")
    if dfd_off != index_end or dfd_len < 4 + 24 or dfd_off + dfd_len > len(data):
        raise ValueError(f"{where}: bad DFD location (offset {dfd_off}, length {dfd_len})")
    total = struct.unpack_from("<I", data, dfd_off)[0]
    if total != dfd_len:
        raise ValueError(f"{where}: dfdTotalSize {total} != dfdByteLength {dfd_len}")
    w = struct.unpack_from(f"<{(dfd_len - 4) // 4}I", data, dfd_off + 4)
    if w[0] != 0 or (w[1] >> 16) != 24 + 16 * nch or dfd_len != 4 + 24 + 16 * nch:
        raise ValueError(f"{where}: DFD is not a basic descriptor with {nch} sample(s)")
    if (w[2] & 0xFF) != KHR_DF_MODEL_RGBSDA or ((w[2] >> 16) & 0xFF) != KHR_DF_TRANSFER_LINEAR:
        raise ValueError(f"{where}: DFD color model / transfer must be RGBSDA / linear")
    premultiplied = bool((w[2] >> 24) & KHR_DF_FLAG_ALPHA_PREMULTIPLIED)
    bits = comp.itemsize * 8
    for i, ch in enumerate(CHANNEL_IDS[:nch]):
        s0 = w[6 + 4 * i]
        exp = (i * bits) | ((bits - 1) << 16) | ((ch | 0xC0) << 24)
        if s0 != exp:
            raise ValueError(f"{where}: DFD sample {i} (0x{s0:08x}) does not describe {fmt} channel {'RGBA'[i]}")
    if kvd_len and (kvd_off != dfd_off + dfd_len or kvd_off + kvd_len > len(data)):
        raise ValueError(f"{where}: bad key/value data location (offset {kvd_off}, length {kvd_len})")
    kv: dict[str, str] = {}
    pos, end = kvd_off, kvd_off + kvd_len
    while pos < end:
        if pos + 4 > end:
            raise ValueError(f"{where}: key/value data truncated")
        n = struct.unpack_from("<I", data, pos)[0]
        entry = data[pos + 4: pos + 4 + n]
        if n < 2 or len(entry) != n or pos + 4 + n > end or b"\0" not in entry:
            raise ValueError(f"{where}: corrupt key/value entry at byte {pos}")
        key, _, value = entry.partition(b"\0")
        try:
            kv[key.decode("utf-8")] = value.rstrip(b"\0").decode("utf-8")
        except UnicodeDecodeError as e:
            raise ValueError(f"{where}: key/value entry at byte {pos} is not UTF-8") from e
        pos = _align(pos + 4 + n, 4)
    texel = nch * comp.itemsize
    align = math.lcm(texel, 4)
    levels: list[NDArray[np.float32]] = []
    nl = max(1, layers)
    for k in range(n_levels):
        off, length, ulength = _LEVEL.unpack_from(data, _HEADER.size + _LEVEL.size * k)
        nk = max(1, width >> k)
        expect = nl * 6 * nk * nk * texel
        if length != expect or ulength != expect:
            raise ValueError(f"{where}: level {k} byteLength {length} (uncompressed {ulength}), expected {expect}")
        if off % align or off < kvd_off + kvd_len:
            raise ValueError(f"{where}: level {k} byteOffset {off} misplaced or not aligned to {align}")
        if off + length > len(data):
            raise ValueError(f"{where}: truncated: level {k} needs bytes {off}..{off + length}, file has {len(data)}")
        a = np.frombuffer(data, dtype=comp.newbyteorder("<"), count=length // comp.itemsize, offset=off)
        shape = ((layers,) if layers else ()) + (6, nk, nk, nch)
        levels.append(a.reshape(shape).astype(np.float32))
    info = {
        "fmt": fmt, "vk_format": vk_format, "size": width, "layers": layers, "level_count": n_levels,
        "layered": layers > 0, "premultiplied": premultiplied, "kv": kv,
    }
    return levels, info


def basic_dfd(fmt: str, premultiplied: bool) -> bytes:
    """The Data Format Descriptor of ``fmt`` (``"rgba16f"`` / ``"rgba32f"``: 92 bytes; ``"r16f"``
    / ``"r32f"``: 44) with its leading ``dfdTotalSize``, as envcap KTX2 files have it
    (``docs/formats.md``)."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown KTX2 format {fmt!r}; expected one of {sorted(FORMATS)}")
    return _dfd(fmt, premultiplied)


def key_value_data(kv: dict[str, str] | None = None) -> bytes:
    """The key/value data block: ``KTXorientation = "rd"``, ``KTXwriter`` and the checked
    entries of ``kv``, sorted by key, each padded to 4 bytes."""
    return _kvd(_check_kv(kv))
