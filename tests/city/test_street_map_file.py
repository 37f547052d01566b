"""The street map in the city index: a KTX2 R16UI file (checked field by field against the KTX
2.0 layout; every field against the specification in tests/formats/test_ktx2_files.py) whose origin
and cell are in city.json, and the lookup world (x, z) -> (street, local frame, probe range)."""

import struct

import numpy as np
import pytest

from envcap.city.locate import load_city_map
from envcap.city.street_map_file import read_street_map, street_map_bytes, write_street_map
from envcap.probeset.city_index import StreetMapInfo, read_city_index
from envcap.probeset.manifest import read_manifest
from envcap.runtime.street_map import StreetMap


def test_the_file_is_a_ktx2_r16_uint_image_by_the_spec(tmp_path):
    ids = np.arange(12, dtype=np.uint16).reshape(3, 4) * 5000  # 3 rows (z) x 4 columns (x), up to 55000
    sm = StreetMap(ids=ids, origin=(-3.5, 1e5), cell=0.25)
    raw = street_map_bytes(sm)
    # KTX 2.0 section 3: identifier, then vkFormat, typeSize, width, height, depth, layers, faces, levels, sc
    assert raw[:12] == bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
    assert struct.unpack_from("<9I", raw, 12) == (74, 2, 4, 3, 0, 0, 1, 1, 0)
    dfd_off, dfd_len, kvd_off, kvd_len = struct.unpack_from("<4I", raw, 48)
    off, length, ulength = struct.unpack_from("<3Q", raw, 80)
    assert (dfd_off, length, ulength) == (104, 24, 24) and off % 4 == 0
    # DFD: total size, basic block header (40 bytes), RGBSDA with primaries and transfer unspecified
    # (integer format, KTX 2.0 3.10.1), one sample: 16-bit unsigned R, sampleLower 0, sampleUpper 1
    words = struct.unpack_from("<11I", raw, dfd_off)
    assert words[0] == dfd_len == 44 and words[2] >> 16 == 40 and words[3] == 1
    assert (words[7] >> 16) & 0xFF == 15 and words[7] >> 24 == 0 and words[9:] == (0, 1)
    kv = raw[kvd_off:kvd_off + kvd_len]
    assert b"KTXorientation\x00rd\x00" in kv and b"envcap" not in kv.replace(b"KTXwriter\x00envcap", b"")
    np.testing.assert_array_equal(np.frombuffer(raw, "<u2", 12, off).reshape(3, 4), ids)
    info = StreetMapInfo("m.ktx2", sm.origin, sm.cell, sm.size)       # city.json's entry: origin and cell
    back = read_street_map(write_street_map(tmp_path / "m.ktx2", sm), info)
    assert (back.origin, back.cell) == (sm.origin, sm.cell)
    np.testing.assert_array_equal(back.ids, ids)


@pytest.mark.parametrize("cut, words", [(lambda b: b[:60], "truncated"),
                                        (lambda b: b"\0" + b[1:], "not a KTX 2.0 file"),
                                        (lambda b: b[:12] + struct.pack("<I", 97) + b[16:], "vkFormat 97 not supported"),
                                        (lambda b: b[:36] + struct.pack("<I", 6) + b[40:], "faceCount 6, expected 1"),
                                        (lambda b: b[:-2], "truncated: level 0 needs bytes")])
def test_a_bad_file_is_named(tmp_path, cut, words):
    path = tmp_path / "m.ktx2"
    path.write_bytes(cut(street_map_bytes(StreetMap(np.ones((3, 4), np.uint16), (0.0, 0.0), 1.0))))
    with pytest.raises(ValueError, match=f"street map {path}: {words}"):
        read_street_map(path, StreetMapInfo("m.ktx2", (0.0, 0.0), 1.0, (4, 3)))


def test_the_map_and_city_json_must_agree(crossing_city):
    info = read_city_index(crossing_city).street_map
    assert read_street_map(crossing_city / info.file, info).size == tuple(info.size) == (300, 300)
    wider = StreetMapInfo(info.file, info.origin, info.cell, (info.size[0] + 1, info.size[1]))
    with pytest.raises(ValueError, match=r"300 x 300 cells, city.json says 301 x 300"):
        read_street_map(crossing_city / info.file, wider)


def test_locate_gives_the_street_its_frame_and_its_probe_range(crossing_city):
    cm = load_city_map(crossing_city)
    ix = read_city_index(crossing_city)
    rng = np.random.default_rng(3)
    x = rng.uniform(-200, 200, 20000)
    z = rng.uniform(-200, 200, 20000)
    got = cm.locate(x, z)
    # independent: the footprint (ends, facades) of each street from its shard's own manifest
    streets = [(s, st) for s, sh in enumerate(ix.shards)
               for st in read_manifest(crossing_city / sh.path / "manifest.json").streets]
    inside = np.zeros((len(streets), x.size), bool)
    for k, (_, st) in enumerate(streets):
        a, c = (x, z) if st.axis == "x" else (z, x)
        inside[k] = (a > st.start + 1) & (a < st.end - 1) & (c > st.planes.facade_min + 1) & (c < st.planes.facade_max - 1)
    only = inside.sum(axis=0) == 1
    none = ~(np.abs(x) < 151) | ~((np.abs(z) < 8) | (np.abs(x) < 8))  # outside both roadways (+1 m)
    assert only.sum() > 500 and none.sum() > 10000
    for k, (s, st) in enumerate(streets):
        sel = only & inside[k]
        layers = sorted(p.layer for p in st.probes)
        assert np.all(got.street[sel] == k) and np.all(got.shard[sel] == s)
        assert np.all(got.along[sel] == (0 if st.axis == "x" else 2))
        assert np.all(got.shard_first[sel] == layers[0]) and np.all(got.count[sel] == len(layers))
        assert np.all(got.city_first[sel] == ix.shards[s].layers[0] + layers[0])
        assert np.all(got.frame_origin[sel] == 0.0)  # probes within 500 m of the world origin
    assert np.all(got.street[none] == -1) and np.all(got.count[none] == 0) and np.all(got.shard[none] == -1)
