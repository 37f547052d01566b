"""KTX2 writer checked with an independent, spec-derived reader (written here byte by byte).

pyktx2 (PyPI, 0.3.1) was tried and cannot serve as the reference: its ColorModel enum lacks
KHR_DF_MODEL_RGBSDA (so it rejects every uncompressed float file), it only knows the stride of
RGBA16F, and its key/value padding uses ``pos % 8``.  The reader below follows the KTX 2.0
specification sections 2 (file structure), 3.9.7 and 3.13 (level index, mip level array) and 3.10
(DFD) directly and imports nothing from envcap.formats.  Every kind of file envcap writes is
checked field by field in test_ktx2_files.py.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest

from envcap.formats.ktx2 import read_ktx2, write_ktx2

KTX2_ID = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])


def spec_read(path):
    """Parse a KTX2 file with plain struct; return header dict, dfd words, kv, level arrays."""
    b = open(path, "rb").read()
    assert b[:12] == KTX2_ID
    names = ["vkFormat", "typeSize", "pixelWidth", "pixelHeight", "pixelDepth", "layerCount",
             "faceCount", "levelCount", "supercompressionScheme"]
    h = dict(zip(names, struct.unpack("<9I", b[12:48])))
    h["dfdByteOffset"], h["dfdByteLength"], h["kvdByteOffset"], h["kvdByteLength"] = struct.unpack("<4I", b[48:64])
    h["sgdByteOffset"], h["sgdByteLength"] = struct.unpack("<2Q", b[64:80])
    idx = [struct.unpack("<3Q", b[80 + 24 * i: 104 + 24 * i]) for i in range(h["levelCount"])]
    d0 = h["dfdByteOffset"]
    dfd_total = struct.unpack("<I", b[d0:d0 + 4])[0]
    assert dfd_total == h["dfdByteLength"]
    dfd = struct.unpack(f"<{(dfd_total - 4) // 4}I", b[d0 + 4:d0 + dfd_total])
    kv = {}
    p, end = h["kvdByteOffset"], h["kvdByteOffset"] + h["kvdByteLength"]
    entries = []
    while p < end:
        n = struct.unpack("<I", b[p:p + 4])[0]
        raw = b[p + 4:p + 4 + n]
        k, v = raw.split(b"\0", 1)
        kv[k.decode()] = v
        entries.append(k)
        p += 4 + n
        p += (-p) % 4  # valuePadding
    assert p == end, "kvdByteLength must include the padding of the last entry"
    comp = {97: np.float16, 109: np.float32}[h["vkFormat"]]
    L = max(1, h["layerCount"])
    levels = []
    for k, (off, length, ulen) in enumerate(idx):
        n = max(1, h["pixelWidth"] >> k)
        assert length == ulen == L * 6 * n * n * 4 * np.dtype(comp).itemsize
        a = np.frombuffer(b[off:off + length], dtype=np.dtype(comp).newbyteorder("<"))
        levels.append(a.reshape(L, 6, n, n, 4))  # layers, then faces, then rows, then texels
    return h, idx, dfd, kv, entries, levels, len(b)


def _rand_levels(rng, n, nlev, layers, dtype=np.float32, scale=100.0):
    out = []
    for k in range(nlev):
        nk = max(1, n >> k)
        shape = ((layers,) if layers else ()) + (6, nk, nk, 4)
        out.append((rng.standard_normal(shape) * scale).astype(dtype))
    return out


@pytest.mark.parametrize("fmt,vk,comp", [("rgba16f", 97, np.float16), ("rgba32f", 109, np.float32)])
@pytest.mark.parametrize("layers", [0, 3])
def test_roundtrip_bit_exact_with_spec_reader(tmp_path, fmt, vk, comp, layers):
    rng = np.random.default_rng(1)
    n, nlev = 8, 4
    src = _rand_levels(rng, n, nlev, layers, dtype=comp)
    path = tmp_path / "c.ktx2"
    write_ktx2(path, src, layered=bool(layers), fmt=fmt, premultiplied=True)
    h, idx, dfd, kv, entries, levels, size = spec_read(path)
    assert h["vkFormat"] == vk and h["typeSize"] == np.dtype(comp).itemsize
    assert (h["pixelWidth"], h["pixelHeight"], h["pixelDepth"]) == (n, n, 0)
    assert h["layerCount"] == layers and h["faceCount"] == 6 and h["levelCount"] == nlev
    assert h["supercompressionScheme"] == 0 and h["sgdByteOffset"] == 0 and h["sgdByteLength"] == 0
    assert h["dfdByteOffset"] == 80 + 24 * nlev
    assert h["kvdByteOffset"] == h["dfdByteOffset"] + h["dfdByteLength"]
    # Bit-exact payload per level (compare raw bits, so -0.0 and denormals count too).
    for k in range(nlev):
        got = levels[k] if layers else levels[k][0]
        uint = np.uint16 if comp is np.float16 else np.uint32
        assert np.array_equal(got.view(uint), src[k].view(uint)), f"level {k} differs"
    # Level index: base level first; data smallest level first, each offset aligned to lcm(texel, 4).
    texel = 4 * np.dtype(comp).itemsize
    offs = [o for o, _, _ in idx]
    assert all(offs[k] > offs[k + 1] for k in range(nlev - 1))
    assert all(o % np.lcm(texel, 4) == 0 for o in offs)
    assert offs[-1] >= h["kvdByteOffset"] + h["kvdByteLength"]
    assert idx[0][0] + idx[0][1] == size  # base level is last in the file
    # KV: sorted by key, NUL-terminated string values, the specification's keys only.
    assert entries == sorted(entries) == [b"KTXorientation", b"KTXwriter"]
    assert kv["KTXorientation"] == b"rd\0"
    assert kv["KTXwriter"].startswith(b"envcap ") and kv["KTXwriter"].endswith(b"\0")
    # DFD: basic block, RGBSDA, BT709, linear, premultiplied, 4 signed-float samples.
    assert dfd[0] == 0  # vendorId Khronos, descriptorType basic
    assert dfd[1] & 0xFFFF == 2 and dfd[1] >> 16 == 24 + 4 * 16  # version 1.3, block size
    assert [(dfd[2] >> s) & 0xFF for s in (0, 8, 16, 24)] == [1, 1, 1, 1]
    assert dfd[3] == 0 and dfd[4] == texel and dfd[5] == 0
    bits = 8 * np.dtype(comp).itemsize
    for i, ch in enumerate((0, 1, 2, 15)):
        w0, pos, lower, upper = dfd[6 + 4 * i: 10 + 4 * i]
        assert w0 & 0xFFFF == i * bits  # bitOffset
        assert (w0 >> 16) & 0xFF == bits - 1  # bitLength - 1
        assert (w0 >> 24) & 0x0F == ch and (w0 >> 24) & 0xF0 == 0xC0  # FLOAT | SIGNED
        assert pos == 0
        assert struct.unpack("<f", struct.pack("<I", lower))[0] == -1.0
        assert struct.unpack("<f", struct.pack("<I", upper))[0] == 1.0
    # envcap's own reader agrees (values and metadata).
    back, info = read_ktx2(path)
    assert info["fmt"] == fmt and info["layers"] == layers and info["premultiplied"]
    assert set(info["kv"]) == {"KTXorientation", "KTXwriter"}
    for k in range(nlev):
        assert back[k].dtype == np.float32 and np.array_equal(back[k], src[k].astype(np.float32))


def test_face_order_and_rows_land_where_gl_expects(tmp_path):
    """Texel (face f, row t, col s) carries (f, t, s): the spec reader finds it at layer/face/row/col."""
    n = 4
    f, t, s = np.meshgrid(np.arange(6), np.arange(n), np.arange(n), indexing="ij")
    cube = np.stack([f, t, s, np.ones_like(f)], axis=-1).astype(np.float32)
    arr = np.stack([cube, cube + 100.0])
    write_ktx2(tmp_path / "a.ktx2", [arr], layered=True, fmt="rgba32f")
    _, _, _, _, _, levels, _ = spec_read(tmp_path / "a.ktx2")
    assert levels[0][1, 3, 2, 1, 0] == 103 and levels[0][1, 3, 2, 1, 1] == 102 and levels[0][1, 3, 2, 1, 2] == 101


def test_one_texel_cube_and_full_chain(tmp_path):
    src = [np.full((6, 2, 2, 4), 2.0, np.float32), np.full((6, 1, 1, 4), 3.0, np.float32)]
    write_ktx2(tmp_path / "a.ktx2", src, layered=False)
    back, info = read_ktx2(tmp_path / "a.ktx2")
    assert info["layers"] == 0 and [b.shape for b in back] == [(6, 2, 2, 4), (6, 1, 1, 4)]
    assert back[1].max() == 3.0
    write_ktx2(tmp_path / "b.ktx2", [np.zeros((1, 6, 1, 1, 4), np.float32)], layered=True)
    assert read_ktx2(tmp_path / "b.ktx2")[0][0].shape == (1, 6, 1, 1, 4)


def test_half_overflow_nan_inf_are_errors(tmp_path):
    a = np.zeros((6, 2, 2, 4), np.float32)
    a[0, 0, 0, 0] = 7e4
    a[1, 0, 0, 1] = -1e5
    with pytest.raises(ValueError, match=r"2 value\(s\) exceed the half-float maximum 65504"):
        write_ktx2(tmp_path / "x.ktx2", [a], layered=False)
    assert not (tmp_path / "x.ktx2").exists()
    write_ktx2(tmp_path / "c.ktx2", [a], layered=False, clamp=True)
    back, _ = read_ktx2(tmp_path / "c.ktx2")
    assert back[0][0, 0, 0, 0] == 65504.0 and back[0][1, 0, 0, 1] == -65504.0
    write_ktx2(tmp_path / "f.ktx2", [a], layered=False, fmt="rgba32f")  # float32 keeps it
    assert read_ktx2(tmp_path / "f.ktx2")[0][0][0, 0, 0, 0] == 7e4
    for bad in (np.nan, np.inf, -np.inf):
        b = np.zeros((6, 2, 2, 4), np.float32)
        b[2, 1, 1, 2] = bad
        with pytest.raises(ValueError, match="NaN or Inf"):
            write_ktx2(tmp_path / "x.ktx2", [b], layered=False, fmt="rgba32f")
    assert list(tmp_path.glob(".*tmp*")) == []  # nothing half-written left behind


def test_bad_arguments(tmp_path):
    p = tmp_path / "x.ktx2"
    ok = np.zeros((6, 4, 4, 4), np.float32)
    with pytest.raises(ValueError, match="unknown KTX2 format"):
        write_ktx2(p, [ok], layered=False, fmt="rgb8")
    with pytest.raises(ValueError, match=r"\(L, 6, N, N, 4\)"):
        write_ktx2(p, [ok], layered=True)
    with pytest.raises(ValueError, match=r"level 1 must have shape \(6, 2, 2, 4\)"):
        write_ktx2(p, [ok, np.zeros((6, 3, 3, 4), np.float32)], layered=False)
    with pytest.raises(ValueError, match="at most 3"):
        write_ktx2(p, [ok] + [np.zeros((6, 1, 1, 4), np.float32)] * 3, layered=False)
    with pytest.raises(ValueError, match="non-empty"):
        write_ktx2(p, [], layered=False)
    with pytest.raises(TypeError, match="kv"):       # no custom key/value entries: JSON beside the file says what it is
        write_ktx2(p, [ok], layered=False, kv={"envcapManifest": "manifest.json"})
    with pytest.raises(ValueError, match="floating-point"):
        write_ktx2(p, [ok.astype(np.int32)], layered=False)
    assert not p.exists()


def _good(tmp_path):
    p = tmp_path / "g.ktx2"
    write_ktx2(p, [np.ones((2, 6, 4, 4, 4), np.float32), np.ones((2, 6, 2, 2, 4), np.float32)], layered=True)
    return p, bytearray(p.read_bytes())


@pytest.mark.parametrize(
    "edit,msg",
    [
        (lambda b: b.__setitem__(slice(0, 4), b"\x00KTX"), "not a KTX 2.0 file"),
        (lambda b: b.__setitem__(slice(12, 16), struct.pack("<I", 37)), "vkFormat 37"),
        (lambda b: b.__setitem__(slice(16, 20), struct.pack("<I", 4)), "typeSize"),
        (lambda b: b.__setitem__(slice(36, 40), struct.pack("<I", 1)), "faceCount 1"),
        (lambda b: b.__setitem__(slice(24, 28), struct.pack("<I", 8)), "square"),
        (lambda b: b.__setitem__(slice(28, 32), struct.pack("<I", 2)), "pixelDepth"),
        (lambda b: b.__setitem__(slice(44, 48), struct.pack("<I", 2)), "supercompressionScheme"),
        (lambda b: b.__setitem__(slice(40, 44), struct.pack("<I", 9)), "levelCount 9"),
        (lambda b: b.__setitem__(slice(48, 52), struct.pack("<I", 7)), "DFD location"),
        (lambda b: b.__setitem__(slice(88, 96), struct.pack("<Q", 12345)), "byteLength"),
    ],
)
def test_corrupt_header_fields_give_clear_errors(tmp_path, edit, msg):
    p, b = _good(tmp_path)
    edit(b)
    p.write_bytes(bytes(b))
    with pytest.raises(ValueError, match=msg):
        read_ktx2(p)


def test_truncated_files(tmp_path):
    p, b = _good(tmp_path)
    for cut in (0, 10, 79, 100, len(b) - 1):
        p.write_bytes(bytes(b[:cut]))
        with pytest.raises(ValueError, match="truncated|DFD location|key/value"):
            read_ktx2(p)
    with pytest.raises(FileNotFoundError, match="not found"):
        read_ktx2(tmp_path / "missing.ktx2")
