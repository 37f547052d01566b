"""Every kind of KTX2 file envcap writes, made by the real code paths (two `envcap capture` bakes with
the opt-in writers and a rung ladder, `envcap prefilter`, a city bake's street map), parsed by a reader
written here from the KTX 2.0 specification (document revision 4; section numbers are its own) and
the Khronos Data Format Specification 1.3 §5 (basic descriptor block), never by envcap's reader, and
checked field by field against what the specification, and KTX-Software's validator
(`tools/ktx/validate.cpp`, which compares a DFD with `vk2dfd`'s in `lib/dfdutils/createdfd.c`),
expect for each vkFormat.  What a file is comes from the JSON beside it (manifest.json,
sky_visibility.json, chain.json, city.json), the place its metadata now lives.

The same checker finds the two faults `ktx validate --warnings-as-errors` reported on files written
before issue 19 (kept in tests/formats/data): the street map's sampleUpper 65535 (error 6028) and
custom keys `envcapStreetMap` / `envcap.lobes` (warning 7010).  ktx-parse (node) reads every file too.
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from test_ktx2_conformance import SPEC_KEYS, ktx_parse

from envcap.cli import main
from envcap.formats.exr_cube import write_exr_cube

DATA = Path(__file__).resolve().parent / "data"
IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])   # §3.1
F32_MINUS_ONE, F32_ONE = struct.unpack("<2I", struct.pack("<2f", -1.0, 1.0))
SIGNED, FLOAT = 0x40, 0x80                        # KDF 1.3 §5 sample qualifiers (channelType bits 6, 7)


@dataclass(frozen=True)
class FormatSpec:
    """What a vkFormat's DFD must be: `vk2dfd` (createDFDUnpacked(0, components, bytes, 0, suffix)) and
    §3.10.1 for integer formats (colorPrimaries and transferFunction UNSPECIFIED)."""

    name: str
    component_bytes: int
    components: int
    integer: bool

    def samples(self) -> list[tuple[int, int, int, int, int, int]]:
        """(bitOffset, bitLength - 1, channel id, qualifiers, sampleLower, sampleUpper) per sample: R, G, B, A
        = 0, 1, 2, 15; float samples FLOAT | SIGNED with -1.0 / 1.0 as float32 bits, whatever their
        size (writeSample, s_SFLOAT); unsigned integer samples 0 / 1 (writeSample, s_UINT: the value
        meaning 1.0, not the largest value)."""
        bits = 8 * self.component_bytes
        q, lo, hi = (0, 0, 1) if self.integer else (FLOAT | SIGNED, F32_MINUS_ONE, F32_ONE)
        return [(i * bits, bits - 1, (0, 1, 2, 15)[i], q, lo, hi) for i in range(self.components)]


FORMATS = {74: FormatSpec("VK_FORMAT_R16_UINT", 2, 1, True),
           76: FormatSpec("VK_FORMAT_R16_SFLOAT", 2, 1, False),
           97: FormatSpec("VK_FORMAT_R16G16B16A16_SFLOAT", 2, 4, False),
           100: FormatSpec("VK_FORMAT_R32_SFLOAT", 4, 1, False),
           109: FormatSpec("VK_FORMAT_R32G32B32A32_SFLOAT", 4, 4, False)}


@dataclass(frozen=True)
class Expect:
    """The texture a file must hold (from the JSON beside it): vkFormat, level-0 size, layerCount,
    faceCount, levelCount, and whether RGB is premultiplied by alpha."""

    vk: int
    width: int
    height: int
    layers: int
    faces: int
    levels: int
    premultiplied: bool = False


def spec_problems(path: Path, want: Expect) -> list[str]:
    """Every way the file at `path` is not the KTX 2.0 file `want` describes (empty: conformant)."""
    b = Path(path).read_bytes()
    bad: list[str] = []

    def check(ok, what):
        if not ok:
            bad.append(what)

    check(b[:12] == IDENTIFIER, "§3.1 identifier")
    (vk, type_size, width, height, depth, layers, faces, levels, scheme) = struct.unpack_from("<9I", b, 12)
    dfd_off, dfd_len, kvd_off, kvd_len = struct.unpack_from("<4I", b, 48)
    sgd_off, sgd_len = struct.unpack_from("<2Q", b, 64)
    fmt = FORMATS[want.vk]
    check(vk == want.vk, f"§3.2 vkFormat is {vk}, expected {want.vk} ({fmt.name})")
    check(type_size == fmt.component_bytes, f"§3.3 typeSize is {type_size}, expected {fmt.component_bytes}")
    check((width, height, depth) == (want.width, want.height, 0), f"§3.4 size {width}x{height}x{depth}")
    check(faces != 6 or width == height, "§3.4 cube faces must be square")
    check(layers == want.layers, f"§3.5 layerCount {layers}, expected {want.layers}")
    check(faces == want.faces, f"§3.6 faceCount {faces}, expected {want.faces}")
    check(levels == want.levels and 1 <= levels <= math.floor(math.log2(max(width, height))) + 1,
          f"§3.7 levelCount {levels}, expected {want.levels}")
    check(scheme == 0, f"§3.8 supercompressionScheme {scheme}")
    # §3.9 index: the DFD right after the level index (4-aligned), the KVD right after the DFD, no SGD
    index_end = 80 + 24 * levels
    check(dfd_off == index_end + (-index_end % 4), f"§3.9.1 dfdByteOffset {dfd_off}")
    check(dfd_len == struct.unpack_from("<I", b, dfd_off)[0] == kvd_off - dfd_off,
          "§3.9.2/§3.10.4 dfdByteLength = dfdTotalSize = kvdByteOffset - dfdByteOffset")
    check(kvd_len > 0, "§3.9.4 key/value data (KTXwriter) missing")
    check((sgd_off, sgd_len) == (0, 0), "§3.9.5/6 sgdByteOffset, sgdByteLength must be 0 without supercompression")

    # §3.10 DFD: one basic descriptor block (KDF 1.3 §5)
    n = fmt.components
    w = struct.unpack_from(f"<{(dfd_len - 4) // 4}I", b, dfd_off + 4)
    check(dfd_len == 4 + 24 + 16 * n, f"§3.10 dfdTotalSize {dfd_len}, expected one block of {n} sample(s)")
    check(w[0] & 0x1FFFF == 0 and w[0] >> 17 == 0, "KDF §5 vendorId 0 (Khronos), descriptorType 0 (basic)")
    check(w[1] & 0xFFFF == 2, "KDF §5 versionNumber 2 (1.3)")
    check(w[1] >> 16 == 24 + 16 * n, f"KDF §5 descriptorBlockSize {w[1] >> 16}")
    model, primaries, transfer, flags = (w[2] >> s & 0xFF for s in (0, 8, 16, 24))
    check(model == 1, f"§3.10.1 colorModel {model}, expected RGBSDA (1)")
    want_cs = (0, 0) if fmt.integer else (1, 1)            # §3.10.1: *_UINT -> UNSPECIFIED, UNSPECIFIED
    check((primaries, transfer) == want_cs, f"§3.10.1 colorPrimaries/transferFunction {primaries}/{transfer}, "
                                            f"expected {want_cs[0]}/{want_cs[1]} for {fmt.name}")
    check(flags == int(want.premultiplied), f"§3.10.3 flags {flags}, expected "
                                            f"{'ALPHA_PREMULTIPLIED' if want.premultiplied else 'ALPHA_STRAIGHT'}")
    check(w[3] == 0, "KDF §5 texelBlockDimension0..3 = 0 (1x1x1x1)")
    check(w[4] == n * fmt.component_bytes and w[5] == 0, f"KDF §5 bytesPlane0 {w[4] & 0xFF}, others 0")
    for i, (off, length, ch, q, lo, hi) in enumerate(fmt.samples()):
        s0, pos, lower, upper = w[6 + 4 * i: 10 + 4 * i]
        check(s0 & 0xFFFF == off, f"sample {i} bitOffset {s0 & 0xFFFF}, expected {off}")
        check(s0 >> 16 & 0xFF == length, f"sample {i} bitLength {s0 >> 16 & 0xFF}, expected {length}")
        check(s0 >> 24 & 0x0F == ch and s0 >> 24 & 0xF0 == q, f"sample {i} channelType 0x{s0 >> 24:02x}")
        check(pos == 0, f"sample {i} samplePosition0..3 {pos}")
        check(lower == lo, f"sample {i} sampleLower is {lower}, expected {lo} for {fmt.name}")
        check(upper == hi, f"sample {i} sampleUpper is {upper}, expected {hi} for {fmt.name}")

    # §3.11 key/value data: well-formed, sorted, zero-padded; §5: only keys the specification defines
    keys, kv, p, end = [], {}, kvd_off, kvd_off + kvd_len
    while p < end:
        size = struct.unpack_from("<I", b, p)[0]
        key, nul, value = b[p + 4: p + 4 + size].partition(b"\0")
        check(size >= 2 and nul == b"\0" and p + 4 + size <= end, f"§3.11 entry at {p}")
        keys.append(key)
        kv[key.decode()] = value
        pad = -size % 4
        check(b[p + 4 + size: p + 4 + size + pad] == b"\0" * pad, f"§3.11 valuePadding at {p}")
        p += 4 + size + pad
    check(p == end, "§3.11 kvdByteLength = entries + padding")
    check(keys == sorted(keys), "§3.11 keys sorted")
    for key in kv:
        check(key in SPEC_KEYS, f"custom key {key!r} (§5 defines the KTX keys; ktx validate warning 7010)")
    check(kv.get("KTXorientation") == b"rd\0", "§5.2 KTXorientation 'rd' (NUL-terminated, 2 letters for 2D and cube maps)")
    check(kv.get("KTXwriter", b"").startswith(b"envcap ") and kv.get("KTXwriter", b"").endswith(b"\0"),
          "§5.5 KTXwriter 'envcap <version>', NUL-terminated")

    # §3.9.7 level index and §3.13 mip level array: level 0 first in the index, smallest level first in
    # the file, each at the next multiple of lcm(texel size, 4) after the one before (zero mipPadding)
    texel = n * fmt.component_bytes
    align = math.lcm(texel, 4)
    pos = end
    for k in reversed(range(levels)):
        off, length, ulength = struct.unpack_from("<3Q", b, 80 + 24 * k)
        size = max(1, layers) * faces * max(1, height >> k) * max(1, width >> k) * texel
        start = pos + (-pos % align)
        check(off == start, f"§3.9.7 level {k} byteOffset {off}, expected {start}")
        check(length == ulength == size, f"§3.9.7 level {k} byteLength {length}/{ulength}, expected {size}")
        check(b[pos:off] == b"\0" * (off - pos), f"§3.13.2 mipPadding before level {k} not zero")
        pos = off + length
    check(pos == len(b), f"level 0 ends at {pos}, the file at {len(b)}")
    return bad


def level_texels(path: Path, k: int, dtype: str) -> np.ndarray:
    """Level `k`'s texels as a flat array, found through the level index alone (§3.9.7)."""
    b = Path(path).read_bytes()
    off, length, _ = struct.unpack_from("<3Q", b, 80 + 24 * k)
    return np.frombuffer(b, dtype=dtype, count=length // np.dtype(dtype).itemsize, offset=off)


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """{kind: (path, Expect)} for every KTX2 file envcap writes, made by the CLI (~5 s in all)."""
    root = tmp_path_factory.mktemp("ktx2_files")
    common = ["--resolution", "16", "--spacing", "300", "--quiet"]
    assert main(["capture", "canyon", *common, "--webgl2", "--sky-visibility", "--inverse-distance",
                 "--out", str(root / "set")]) == 0
    assert main(["capture", "canyon", *common, "--ladder", "half_octave", "--out", str(root / "rungs")]) == 0
    assert main(["capture", "crossing", "--resolution", "8", "--spacing", "100", "--workers", "0", "--shard-mb", "0",
                 "--out", str(root / "city")]) == 0
    rng = np.random.default_rng(3)
    write_exr_cube(root / "env.exr", (rng.random((6, 8, 8, 4)) * 50).astype(np.float32))
    assert main(["prefilter", str(root / "env.exr"), "--out", str(root / "chain")]) == 0

    out = {}
    s = root / "set"
    m = json.loads((s / "manifest.json").read_text())
    n, k, layers = m["resolution"], len(m["levels"]), sum(len(st["probes"]) for st in m["streets"])
    out["probes.ktx2: cube-map array RGBA16F, premultiplied"] = (s / m["files"]["probes"],
                                                                Expect(97, n, n, layers, 6, k, True))
    out["sky.ktx2: cube map RGBA32F"] = (s / m["files"]["sky"], Expect(109, n, n, 0, 6, k))
    from envcap.formats.face_atlas import face_atlas_layout
    lay = face_atlas_layout(n, k)
    out["probes_atlas.ktx2: 2D array RGBA16F for WebGL2, premultiplied"] = (
        s / m["files"]["probes_atlas"], Expect(97, lay.width, lay.height, 6 * layers, 1, 1, True))
    t = json.loads((s / m["files"]["sky_visibility_table"]).read_text())
    first, sizes = t["first_level"], t["ladder"]["sizes"]
    out["sky_visibility.ktx2: cube-map array RGBA16F moments"] = (
        s / m["files"]["sky_visibility"],
        Expect(97, sizes[first], sizes[first], layers * t["layers_per_probe"], 6, len(sizes) - first))
    out["inverse_distance.ktx2: cube-map array R16F"] = (s / m["files"]["inverse_distance"],
                                                        Expect(76, n, n, layers, 6, 1))
    r = root / "rungs"
    m = json.loads((r / "manifest.json").read_text())
    lad = m["ladder"]
    rl = sum(len(st["probes"]) for st in m["streets"]) * lad["per_level"]
    out["rung ladder probes.ktx2"] = (r / m["files"]["probes"],
                                      Expect(97, lad["sizes"][0], lad["sizes"][0], rl, 6, len(lad["sizes"]), True))
    out["rung ladder sky.ktx2"] = (r / m["files"]["sky"], Expect(109, lad["sizes"][0], lad["sizes"][0],
                                                                 lad["per_level"], 6, len(lad["sizes"])))
    c = json.loads((root / "city" / "city.json").read_text())
    cols, rows = c["street_map"]["size"]
    out["street_map.ktx2: 2D R16_UINT"] = (root / "city" / c["street_map"]["file"], Expect(74, cols, rows, 0, 1, 1))
    shard = root / "city" / c["shards"][0]["path"]
    sl = c["shards"][0]["layers"][1]
    out["city shard probes.ktx2"] = (shard / "probes.ktx2", Expect(97, 8, 8, sl, 6, len(c["levels"]), True))
    ch = json.loads((root / "chain" / "chain.json").read_text())
    out["prefilter chain.ktx2: cube map RGBA32F"] = (root / "chain" / ch["ktx2"],
                                                     Expect(109, ch["sizes"][0], ch["sizes"][0], 0, 6, len(ch["sizes"])))
    assert {p.name for p, _ in out.values()} >= {p.name for p in root.rglob("*.ktx2")}   # nothing missed
    return out


def test_every_file_is_the_spec_file_for_its_vkformat(made):
    for kind, (path, want) in made.items():
        assert spec_problems(path, want) == [], f"{kind} ({path.name})"


def test_the_files_pass_ktx_parse_and_hold_what_envcap_reads(made):
    """ktx-parse (three.js's parser) reads each file to the same header and the spec's keys alone, and
    writes the parsed container back to the same bytes; envcap's readers give the texels the level index
    points at."""
    from envcap.city.street_map_file import read_street_map
    from envcap.formats.ktx2 import read_ktx2
    from envcap.probeset.city_index import read_city_index

    kinds = list(made)
    for kind, f in zip(kinds, ktx_parse(*(made[k][0] for k in kinds))):
        want = made[kind][1]
        assert (f["vkFormat"], f["pixelWidth"], f["pixelHeight"], f["layerCount"], f["faceCount"], f["levelCount"]) == \
            (want.vk, want.width, want.height, want.layers, want.faces, want.levels), kind
        assert set(f["keyValue"]) == {"KTXorientation", "KTXwriter"} and f["rewriteIdentical"], kind
    for kind, (path, want) in made.items():
        if want.vk == 74:
            city = path.parent
            sm = read_street_map(path, read_city_index(city).street_map)
            np.testing.assert_array_equal(sm.ids.reshape(-1), level_texels(path, 0, "<u2"))
            assert sm.ids.max() == 2 and (sm.ids == 0).any()          # two streets and the sky between
        elif want.faces == 6:
            levels, info = read_ktx2(path)
            dtype = "<f2" if FORMATS[want.vk].component_bytes == 2 else "<f4"
            for k, a in enumerate(levels):
                np.testing.assert_array_equal(a.reshape(-1), level_texels(path, k, dtype).astype(np.float32))
            assert info["premultiplied"] == want.premultiplied and set(info["kv"]) == {"KTXorientation", "KTXwriter"}


def test_the_metadata_moved_into_the_json_beside_the_files(made):
    from envcap.core.lobes import lobe_ladder

    chain_ktx2 = made["prefilter chain.ktx2: cube map RGBA32F"][0]
    ch = json.loads((chain_ktx2.parent / "chain.json").read_text())
    assert ch["lobes"] == lobe_ladder(8).to_manifest() and ch["ktx2"] == chain_ktx2.name   # was `envcap.lobes`
    street_map = made["street_map.ktx2: 2D R16_UINT"][0]
    info = json.loads((street_map.parent / "city.json").read_text())["street_map"]
    assert info["file"] == street_map.name and info["cell"] == 1.0                     # was `envcapStreetMap`
    assert info["origin"] == [-150.0, -150.0] and info["size"] == [300, 300]             # crossing: +-150 m


OLD_STREET_MAP = Expect(74, 4, 3, 0, 1, 1)
OLD_CHAIN = Expect(109, 4, 4, 0, 6, 3)


def test_the_checker_finds_what_ktx_validate_reported_on_older_files():
    """Files written before issue 19 (tests/formats/data): `ktx validate` error 6028 on the street map
    (sampleUpper 65535 where R16_UINT has 1) and warning 7010 on the custom keys."""
    old_map = spec_problems(DATA / "street_map_before_issue19.ktx2", OLD_STREET_MAP)
    assert "sample 0 sampleUpper is 65535, expected 1 for VK_FORMAT_R16_UINT" in old_map
    assert any("custom key 'envcapStreetMap'" in p for p in old_map)
    assert any("colorPrimaries/transferFunction 0/1" in p for p in old_map)     # transfer LINEAR on an integer format
    assert spec_problems(DATA / "chain_before_issue19.ktx2", OLD_CHAIN) == [
        "custom key 'envcap.lobes' (§5 defines the KTX keys; ktx validate warning 7010)"]


def test_older_files_still_read(tmp_path):
    """The readers take files written before issue 19: the custom keys are read like any and needed by
    nothing (the chain's lobes are in chain.json, the map's origin and cell in city.json); the street
    map's old DFD is accepted as that version's (envcap.city.street_map_file.DFD_BEFORE_ISSUE_19)."""
    from envcap.city.street_map_file import read_street_map, street_map_bytes
    from envcap.formats.ktx2 import read_ktx2
    from envcap.probeset.city_index import StreetMapInfo
    from envcap.runtime.street_map import StreetMap

    sm = read_street_map(DATA / "street_map_before_issue19.ktx2", StreetMapInfo("m.ktx2", (-3.5, 1e5), 0.25, (4, 3)))
    np.testing.assert_array_equal(sm.ids, np.arange(12, dtype=np.uint16).reshape(3, 4) * 5000)
    assert (sm.origin, sm.cell) == ((-3.5, 1e5), 0.25)
    levels, info = read_ktx2(DATA / "chain_before_issue19.ktx2")
    assert [a.shape for a in levels] == [(6, 4, 4, 4), (6, 2, 2, 4), (6, 1, 1, 4)] and "envcap.lobes" in info["kv"]
    # any other DFD for R16_UINT is refused, naming the field
    info = StreetMapInfo("m.ktx2", (0.0, 0.0), 1.0, (4, 3))
    good = street_map_bytes(StreetMap(np.ones((3, 4), np.uint16), (0.0, 0.0), 1.0))
    for word, value, words in ((3, 1 | 1 << 16, r"transferFunction is 0x01 \(1\), expected 0x00 \(0\)"),
                               (10, 255, r"sample 0 sampleUpper is 0x000000ff \(255\), expected 0x00000001 \(1\)")):
        raw = bytearray(good)
        struct.pack_into("<I", raw, 104 + 4 * word, value)   # word 0: dfdTotalSize (the DFD is at 104)
        (tmp_path / "m.ktx2").write_bytes(bytes(raw))
        with pytest.raises(ValueError, match=f"street map .*m.ktx2: DFD {words} for VK_FORMAT_R16_UINT"):
            read_street_map(tmp_path / "m.ktx2", info)
