"""The KTX 2.0 container: the one writer (and reader) of every KTX2 file envcap writes.

Written from the KTX 2.0 specification, document revision 4 (https://registry.khronos.org/KTX/specs/2.0/,
section numbers below are its own) and the Khronos Data Format Specification 1.3 (KDF, §5: the
basic descriptor block).  Format modules name a vkFormat (:data:`VK_FORMATS`), say the texture's
shape (:class:`Ktx2Shape`: 2D or cube map, array or not, mip levels) and hand over their levels'
texels; this module owns everything else:

* header (§3.1–§3.8): ``typeSize`` = the component size, ``pixelDepth`` 0, no supercompression;
  index (§3.9) and level index (§3.9.7), level 0 first; no supercompression global data;
* data format descriptor (§3.10): one basic block (KDF §5), the one KTX-Software's ``vk2dfd``
  builds for the vkFormat (``lib/dfdutils/createdfd.c``, ``createDFDUnpacked``), which is what
  ``ktx validate`` compares a file's block with (``tools/ktx/validate.cpp``: samples, bytesPlanes,
  block dimensions; error 6028 for a sample field), with the two fields §3.10 asks a writer to
  fill itself: ``flags`` = ``KHR_DF_FLAG_ALPHA_PREMULTIPLIED`` when RGB is premultiplied by A
  (§3.10.3, "Premultiplied Alpha"), and for the integer formats (``*_UINT``) ``colorPrimaries``
  and ``transferFunction`` UNSPECIFIED (§3.10.1, "Restrictions"; vk2dfd writes BT709 / LINEAR
  there and the validator checks neither).  Samples: one per component, R, G, B, A = channel ids
  0, 1, 2, 15; a float sample has qualifiers FLOAT | SIGNED and ``sampleLower`` / ``sampleUpper``
  the float32 bit patterns of -1.0 / 1.0 (half samples too); an unsigned integer sample has no
  qualifier and ``sampleLower`` 0, ``sampleUpper`` 1 (the value that means 1, not the largest
  value the sample holds);
* key/value data (§3.11): exactly ``KTXorientation = "rd"`` (§5.2: s to the right, t down, row 0 of
  every image first, as envcap's arrays are) and ``KTXwriter = "envcap <version>"`` (§5.5), sorted,
  NUL-terminated, each padded to 4 bytes.  No other key: the specification defines no key for
  application data (``ktx validate`` warns 7010 about any), so what a file is goes in the JSON
  beside it (``docs/formats.md``);
* mip level array (§3.13): smallest level first, each level at a multiple of ``lcm(texel size, 4)``
  with zero ``mipPadding`` between; within a level, layers, then faces, then rows, then texels:
  the C order of an array ``(max(1, layers), faces, height_k, width_k, components)``.

Writes are atomic (:func:`envcap.outputs.atomic_output_file`) and stream: the caller's level writer
is called once per level, smallest first.  :func:`read_ktx2_file` checks every field it depends on
and names the first one that is not what this module writes.
"""

from __future__ import annotations

import io
import math
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Callable, Collection, Sequence

import numpy as np
from numpy.typing import NDArray

from envcap import __version__
from envcap.outputs import atomic_output_file

IDENTIFIER = b"\xabKTX 20\xbb\r\n\x1a\n"
"""The 12-byte KTX 2.0 file identifier (§3.1)."""

HEADER = struct.Struct("<12s9I4I2Q")
"""Identifier, the nine UInt32 header fields (§3.2–§3.8), the DFD and KVD offsets and lengths
(UInt32) and the SGD offset and length (UInt64) (§3.9): 80 bytes."""

LEVEL_ENTRY = struct.Struct("<3Q")
"""One level index entry (§3.9.7): byteOffset, byteLength, uncompressedByteLength."""

ORIENTATION = "rd"
"""``KTXorientation`` of every envcap file (§5.2)."""


@dataclass(frozen=True)
class VkFormat:
    """A Vulkan format envcap writes: its enum ``value`` and ``name``, its little-endian component
    type and its components (1: R; 4: R, G, B, A)."""

    value: int
    name: str
    component: np.dtype
    components: int

    @property
    def integer(self) -> bool:
        """An unsigned integer format (``*_UINT``), else a signed float one (``*_SFLOAT``)."""
        return self.component.kind == "u"

    @property
    def texel_bytes(self) -> int:
        """Bytes per texel (the texel block size of §3.13.2)."""
        return self.components * self.component.itemsize


R16_UINT = VkFormat(74, "VK_FORMAT_R16_UINT", np.dtype("<u2"), 1)
R16_SFLOAT = VkFormat(76, "VK_FORMAT_R16_SFLOAT", np.dtype("<f2"), 1)
R16G16B16A16_SFLOAT = VkFormat(97, "VK_FORMAT_R16G16B16A16_SFLOAT", np.dtype("<f2"), 4)
R32_SFLOAT = VkFormat(100, "VK_FORMAT_R32_SFLOAT", np.dtype("<f4"), 1)
R32G32B32A32_SFLOAT = VkFormat(109, "VK_FORMAT_R32G32B32A32_SFLOAT", np.dtype("<f4"), 4)

VK_FORMATS: dict[int, VkFormat] = {f.value: f for f in (R16_UINT, R16_SFLOAT, R16G16B16A16_SFLOAT,
                                                        R32_SFLOAT, R32G32B32A32_SFLOAT)}
"""Every vkFormat envcap writes, by value."""

# Khronos Data Format constants (KDF §5; KTX-Software KHR/khr_df.h)
KHR_DF_VERSIONNUMBER_1_3, KHR_DF_MODEL_RGBSDA, KHR_DF_FLAG_ALPHA_PREMULTIPLIED = 2, 1, 1
KHR_DF_PRIMARIES_UNSPECIFIED, KHR_DF_PRIMARIES_BT709 = 0, 1
KHR_DF_TRANSFER_UNSPECIFIED, KHR_DF_TRANSFER_LINEAR = 0, 1
KHR_DF_SAMPLE_DATATYPE_SIGNED, KHR_DF_SAMPLE_DATATYPE_FLOAT = 0x40, 0x80
CHANNEL_IDS = (0, 1, 2, 15)
"""RGBSDA channel ids of the samples R, G, B, A."""
FLOAT_MINUS_ONE, FLOAT_ONE = 0xBF800000, 0x3F800000   # -1.0f, 1.0f as float32 bits

LevelWriter = Callable[[BinaryIO, int], None]
"""``write_level(f, k)`` appends level ``k``'s texels to ``f``: exactly :meth:`Ktx2Shape.level_bytes`
bytes, little-endian, in the order of :meth:`Ktx2Shape.level_shape`."""


@dataclass(frozen=True)
class Ktx2Shape:
    """The texture a KTX2 file holds (§4.1 "Texture Type"): ``width`` x ``height`` texels at level
    0 (both >= 1: envcap writes no 1D or 3D textures), ``layers`` (``layerCount``, 0 = not an
    array), ``faces`` (1, or 6 for a cube map: square faces) and ``levels`` mip levels, level ``k``
    of ``max(1, width >> k)`` x ``max(1, height >> k)`` texels."""

    fmt: VkFormat
    width: int
    height: int
    layers: int = 0
    faces: int = 1
    levels: int = 1

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"a KTX2 texture needs width and height >= 1, got {self.width} x {self.height}")
        if self.faces not in (1, 6) or (self.faces == 6 and self.width != self.height):
            raise ValueError(f"faceCount must be 1 or 6 (square faces), got {self.faces} of "
                             f"{self.width} x {self.height}")
        if self.layers < 0:
            raise ValueError(f"layerCount must be >= 0, got {self.layers}")
        if not 1 <= self.levels <= max_levels(self.width, self.height):
            raise ValueError(f"{self.levels} levels given, but a {self.width} x {self.height} texture has "
                             f"at most {max_levels(self.width, self.height)}")

    def level_size(self, k: int) -> tuple[int, int]:
        """``(width_k, height_k)`` of level ``k``."""
        return max(1, self.width >> k), max(1, self.height >> k)

    def level_shape(self, k: int) -> tuple[int, int, int, int, int]:
        """``(max(1, layers), faces, height_k, width_k, components)``: level ``k`` in C order."""
        w, h = self.level_size(k)
        return (max(1, self.layers), self.faces, h, w, self.fmt.components)

    def level_bytes(self, k: int) -> int:
        """Bytes of level ``k`` (its ``byteLength`` = ``uncompressedByteLength``)."""
        return math.prod(self.level_shape(k)) * self.fmt.component.itemsize


def max_levels(width: int, height: int) -> int:
    """``floor(log2(max(width, height))) + 1``: the most levels a texture has (§3.7)."""
    return max(width, height).bit_length()


def basic_dfd(fmt: VkFormat, *, premultiplied: bool = False) -> bytes:
    """The data format descriptor envcap writes for ``fmt`` (see the module docstring), with its
    leading ``dfdTotalSize``: ``4 + 24 + 16 * components`` bytes.  ``premultiplied`` needs alpha."""
    if premultiplied and fmt.components != 4:
        raise ValueError(f"premultiplied alpha needs an alpha channel; {fmt.name} has none")
    bits = 8 * fmt.component.itemsize
    n = fmt.components
    if fmt.integer:
        primaries, transfer, qualifiers, lower, upper = (KHR_DF_PRIMARIES_UNSPECIFIED, KHR_DF_TRANSFER_UNSPECIFIED,
                                                         0, 0, 1)
    else:
        primaries, transfer, lower, upper = KHR_DF_PRIMARIES_BT709, KHR_DF_TRANSFER_LINEAR, FLOAT_MINUS_ONE, FLOAT_ONE
        qualifiers = KHR_DF_SAMPLE_DATATYPE_FLOAT | KHR_DF_SAMPLE_DATATYPE_SIGNED
    flags = KHR_DF_FLAG_ALPHA_PREMULTIPLIED if premultiplied else 0
    words = [0,                                          # vendorId Khronos, descriptorType basic
             ((24 + 16 * n) << 16) | KHR_DF_VERSIONNUMBER_1_3,
             KHR_DF_MODEL_RGBSDA | (primaries << 8) | (transfer << 16) | (flags << 24),
             0,                                          # texelBlockDimension0..3: 1x1x1x1 (stored minus one)
             n * fmt.component.itemsize,                 # bytesPlane0 = texel size, bytesPlane1..3 = 0
             0]                                          # bytesPlane4..7
    for i, ch in enumerate(CHANNEL_IDS[:n]):
        words += [(i * bits) | ((bits - 1) << 16) | ((ch | qualifiers) << 24), 0, lower, upper]
    body = struct.pack(f"<{len(words)}I", *words)
    return struct.pack("<I", 4 + len(body)) + body


def key_value_data() -> bytes:
    """The key/value data of every envcap file: ``KTXorientation``, ``KTXwriter`` (sorted by key
    bytes), each ``UInt32 keyAndValueByteLength, key, NUL, value, NUL`` padded to 4 bytes."""
    out = bytearray()
    for key, value in sorted({"KTXorientation": ORIENTATION, "KTXwriter": f"envcap {__version__}"}.items()):
        entry = key.encode() + b"\0" + value.encode() + b"\0"
        out += struct.pack("<I", len(entry)) + entry + b"\0" * (-len(entry) % 4)
    return bytes(out)


def _align(x: int, a: int) -> int:
    return -(-x // a) * a


def write_ktx2_to(f: BinaryIO, shape: Ktx2Shape, write_level: LevelWriter, *, premultiplied: bool = False) -> None:
    """Write the KTX2 file of ``shape`` to the binary stream ``f`` (at its position 0): header,
    level index, DFD, key/value data, then each level from ``write_level``, smallest first, with
    its ``mipPadding``.  ``ValueError`` if a level writer writes other than its level's bytes."""
    dfd = basic_dfd(shape.fmt, premultiplied=premultiplied)
    kvd = key_value_data()
    n = shape.levels
    dfd_off = HEADER.size + LEVEL_ENTRY.size * n
    kvd_off = dfd_off + len(dfd)
    align = math.lcm(shape.fmt.texel_bytes, 4)
    offsets = [0] * n
    pos = kvd_off + len(kvd)
    for k in reversed(range(n)):
        pos = _align(pos, align)
        offsets[k] = pos
        pos += shape.level_bytes(k)
    f.write(HEADER.pack(IDENTIFIER, shape.fmt.value, shape.fmt.component.itemsize, shape.width, shape.height, 0,
                        shape.layers, shape.faces, n, 0, dfd_off, len(dfd), kvd_off, len(kvd), 0, 0))
    f.write(b"".join(LEVEL_ENTRY.pack(offsets[k], shape.level_bytes(k), shape.level_bytes(k)) for k in range(n)))
    f.write(dfd + kvd)
    end = kvd_off + len(kvd)
    for k in reversed(range(n)):
        f.write(b"\0" * (offsets[k] - end))
        write_level(f, k)
        end = offsets[k] + shape.level_bytes(k)
        if f.tell() != end:
            raise ValueError(f"level {k}: {f.tell() - offsets[k]} bytes written, {shape.fmt.name} "
                             f"level of shape {shape.level_shape(k)} has {shape.level_bytes(k)}")


def write_ktx2_file(path: str | os.PathLike[str], shape: Ktx2Shape, write_level: LevelWriter, *,
                    premultiplied: bool = False) -> Path:
    """Write the KTX2 file of ``shape`` at ``path`` atomically (nothing is left at ``path`` if a
    level writer raises); return the path.  See :func:`write_ktx2_to`."""
    final = Path(path)
    with atomic_output_file(final) as tmp:
        with open(tmp, "wb") as f:
            write_ktx2_to(f, shape, write_level, premultiplied=premultiplied)
    return final


def array_levels(levels: Sequence[NDArray], shape: Ktx2Shape) -> LevelWriter:
    """The level writer of arrays already in ``shape.fmt``'s component type: ``levels[k]`` of
    :meth:`Ktx2Shape.level_shape` (or any shape of that many components), written as-is."""
    if len(levels) != shape.levels:
        raise ValueError(f"{len(levels)} levels given for a texture of {shape.levels}")
    for k, a in enumerate(levels):
        a = np.asarray(a)
        if a.dtype.newbyteorder("<") != shape.fmt.component or a.size * a.itemsize != shape.level_bytes(k):
            raise ValueError(f"level {k}: {a.dtype} array of shape {a.shape}, "
                             f"{shape.fmt.name} needs {shape.level_shape(k)} of {shape.fmt.component}")

    def write(f: BinaryIO, k: int) -> None:
        f.write(np.ascontiguousarray(levels[k], dtype=shape.fmt.component).tobytes())
    return write


def ktx2_bytes(shape: Ktx2Shape, write_level: LevelWriter, *, premultiplied: bool = False) -> bytes:
    """The whole file of :func:`write_ktx2_to`, in memory."""
    buf = io.BytesIO()
    write_ktx2_to(buf, shape, write_level, premultiplied=premultiplied)
    return buf.getvalue()


_DFD_WORDS = (  # (field, shift, bits) per 32-bit word of the basic block (KDF 1.3 §5), then per sample word
    (("vendorId", 0, 17), ("descriptorType", 17, 15)),
    (("versionNumber", 0, 16), ("descriptorBlockSize", 16, 16)),
    (("colorModel", 0, 8), ("colorPrimaries", 8, 8), ("transferFunction", 16, 8), ("flags", 24, 8)),
    (("texelBlockDimension0..3", 0, 32),),
    (("bytesPlane0..3", 0, 32),),
    (("bytesPlane4..7", 0, 32),),
)
_SAMPLE_WORDS = (
    (("bitOffset", 0, 16), ("bitLength", 16, 8), ("channelType", 24, 8)),
    (("samplePosition0..3", 0, 32),),
    (("sampleLower", 0, 32),),
    (("sampleUpper", 0, 32),),
)


def dfd_difference(got: bytes, want: bytes) -> str | None:
    """The first field where the DFD ``got`` differs from ``want`` (both with ``dfdTotalSize``),
    named with both values; ``None`` when they are equal."""
    if got == want:
        return None
    if len(got) != len(want):
        return (f"DFD dfdTotalSize is {len(got)}, expected {len(want)} "
                f"(one basic block of {(len(want) - 28) // 16} sample(s))")
    g = struct.unpack(f"<{len(got) // 4}I", got)
    w = struct.unpack(f"<{len(want) // 4}I", want)
    i = next(i for i in range(1, len(g)) if g[i] != w[i])
    if i <= 6:
        fields, prefix = _DFD_WORDS[i - 1], ""
    else:
        fields, prefix = _SAMPLE_WORDS[(i - 7) % 4], f"sample {(i - 7) // 4} "
    for name, shift, bits in fields:
        a, b = (g[i] >> shift) & ((1 << bits) - 1), (w[i] >> shift) & ((1 << bits) - 1)
        if a != b:
            return f"DFD {prefix}{name} is 0x{a:0{bits // 4}x} ({a}), expected 0x{b:0{bits // 4}x} ({b})"
    raise AssertionError("unreachable: the words differ")


@dataclass(frozen=True)
class Ktx2Contents:
    """A KTX2 file read by :func:`read_ktx2_file`: its ``shape``, the DFD's premultiplied flag,
    its key/value entries (``kv``: UTF-8 string values, NUL terminator removed; entries whose value
    is not UTF-8 are left out) and its levels, level ``k`` a read-only array of
    :meth:`Ktx2Shape.level_shape` in the format's little-endian component type."""

    shape: Ktx2Shape
    premultiplied: bool
    kv: dict[str, str]
    levels: list[NDArray]


def read_ktx2_file(path: str | os.PathLike[str], *, formats: Collection[VkFormat], faces: int,
                   what: str = "KTX2 file", legacy_dfds: Collection[bytes] = ()) -> Ktx2Contents:
    """Read a KTX2 file of one of ``formats`` with ``faces`` faces, written by this module or any
    writer of the same subset (no supercompression, 2D levels), checking every field it uses.

    The DFD must be :func:`basic_dfd` of the file's vkFormat (premultiplied or not) or one of
    ``legacy_dfds`` (what an older envcap wrote for a format, accepted by its module).  Keys other
    than the specification's are read and returned, never needed (§4, "Extending KTX": readers
    ignore metadata they do not handle).  ``FileNotFoundError`` for a missing file; ``ValueError`` naming ``what``, the
    file and the first field that is wrong (truncation included)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{what} not found: {p}")
    data = p.read_bytes()
    where = f"{what} {p}"
    if len(data) < HEADER.size:
        raise ValueError(f"{where}: truncated ({len(data)} bytes, the header needs {HEADER.size})")
    (ident, vk, type_size, width, height, depth, layers, n_faces, n_levels, scheme,
     dfd_off, dfd_len, kvd_off, kvd_len, sgd_off, sgd_len) = HEADER.unpack_from(data, 0)
    if ident != IDENTIFIER:
        raise ValueError(f"{where}: not a KTX 2.0 file (bad identifier {ident!r})")
    by_value = {f.value: f for f in formats}
    if vk not in by_value:
        raise ValueError(f"{where}: vkFormat {vk} not supported (expected "
                         f"{', '.join(f'{f.value} {f.name}' for f in formats)})")
    fmt = by_value[vk]
    if type_size != fmt.component.itemsize:
        raise ValueError(f"{where}: typeSize {type_size} does not match {fmt.name} "
                         f"(expected {fmt.component.itemsize})")
    if n_faces != faces:
        raise ValueError(f"{where}: faceCount {n_faces}, expected {faces} "
                         f"({'a cube map' if faces == 6 else 'no cube map'})")
    if width < 1 or height < 1 or (faces == 6 and width != height):
        raise ValueError(f"{where}: {'cube faces must be square and non-empty' if faces == 6 else 'empty image'}, "
                         f"got {width}x{height}")
    if depth != 0:
        raise ValueError(f"{where}: pixelDepth {depth}, expected 0 (envcap writes no 3D textures)")
    if scheme != 0:
        raise ValueError(f"{where}: supercompressionScheme {scheme} not supported (expected 0, none)")
    if not 1 <= n_levels <= max_levels(width, height):
        raise ValueError(f"{where}: levelCount {n_levels} invalid for {width}x{height} "
                         f"(1..{max_levels(width, height)})")
    if sgd_off != 0 or sgd_len != 0:
        raise ValueError(f"{where}: unexpected supercompression global data")
    shape = Ktx2Shape(fmt, width, height, layers, n_faces, n_levels)
    index_end = HEADER.size + LEVEL_ENTRY.size * n_levels
    if len(data) < index_end:
        raise ValueError(f"{where}: truncated in the level index")
    if dfd_off != index_end or dfd_len < 4 + 24 or dfd_off + dfd_len > len(data):
        raise ValueError(f"{where}: bad DFD location (offset {dfd_off}, length {dfd_len})")
    total = struct.unpack_from("<I", data, dfd_off)[0]
    if total != dfd_len:
        raise ValueError(f"{where}: dfdTotalSize {total} != dfdByteLength {dfd_len}")
    dfd = data[dfd_off:dfd_off + dfd_len]
    premultiplied = fmt.components == 4 and dfd == basic_dfd(fmt, premultiplied=True)
    if not premultiplied and dfd != basic_dfd(fmt) and dfd not in legacy_dfds:
        raise ValueError(f"{where}: {dfd_difference(dfd, basic_dfd(fmt))} for {fmt.name}")
    kv_end = dfd_off + dfd_len
    if kvd_len:
        if kvd_off != kv_end or kvd_off + kvd_len > len(data):
            raise ValueError(f"{where}: bad key/value data location (offset {kvd_off}, length {kvd_len})")
        kv_end = kvd_off + kvd_len
    elif kvd_off != 0:
        raise ValueError(f"{where}: bad key/value data location (offset {kvd_off} without data)")
    kv = _read_kv(data, kvd_off, kvd_off + kvd_len, where)
    align = math.lcm(fmt.texel_bytes, 4)
    levels: list[NDArray] = []
    for k in range(n_levels):
        off, length, ulength = LEVEL_ENTRY.unpack_from(data, HEADER.size + LEVEL_ENTRY.size * k)
        expect = shape.level_bytes(k)
        if length != expect or ulength != expect:
            raise ValueError(f"{where}: level {k} byteLength {length} (uncompressed {ulength}), expected {expect}")
        if off % align or off < kv_end:
            raise ValueError(f"{where}: level {k} byteOffset {off} misplaced or not aligned to {align}")
        if off + length > len(data):
            raise ValueError(f"{where}: truncated: level {k} needs bytes {off}..{off + length}, file has {len(data)}")
        levels.append(np.frombuffer(data, dtype=fmt.component, count=length // fmt.component.itemsize,
                                    offset=off).reshape(shape.level_shape(k)))
    return Ktx2Contents(shape, premultiplied, kv, levels)


def _read_kv(data: bytes, pos: int, end: int, where: str) -> dict[str, str]:
    kv: dict[str, str] = {}
    while pos < end:
        if pos + 4 > end:
            raise ValueError(f"{where}: key/value data truncated")
        n = struct.unpack_from("<I", data, pos)[0]
        entry = data[pos + 4: pos + 4 + n]
        if n < 2 or pos + 4 + n > end or b"\0" not in entry:
            raise ValueError(f"{where}: corrupt key/value entry at byte {pos}")
        key, _, value = entry.partition(b"\0")
        try:
            name = key.decode("utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{where}: key/value entry at byte {pos}: the key is not UTF-8") from None
        try:
            kv[name] = value[:-1].decode("utf-8") if value.endswith(b"\0") else value.decode("utf-8")
        except UnicodeDecodeError:
            pass                        # a binary value (§3.11 allows them): not a key envcap reads
        pos += 4 + n + (-n % 4)
    return kv
