"""The probe set's KTX2 files (probes.ktx2, sky.ktx2, and the opt-in WebGL2 probes_atlas.ktx2) read
by an independent reader, ktx-parse (the parser three.js's KTX2Loader uses, run with node), and
checked against the KTX 2.0 specification's rules that `ktx validate` applies, among them: no
custom key/value entries (its warning 7010), keys sorted and NUL-terminated, 4-byte padding."""

import hashlib
import json
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from envcap.formats.face_atlas import face_atlas, face_atlas_layout
from envcap.probeset.store import write_probe_set

KTX_PARSE = Path(__file__).resolve().parent / "ktx_parse"
DATA = Path(__file__).resolve().parent / "data"
# The keys the KTX 2.0 specification defines (section 5.7 "Key/Value Data"); any other key is
# application-defined, which `ktx validate` reports as warning 7010.
SPEC_KEYS = {"KTXcubemapIncomplete", "KTXorientation", "KTXglFormat", "KTXdxgiFormat__", "KTXmetalPixelFormat",
             "KTXswizzle", "KTXwriter", "KTXwriterScParams", "KTXastcDecodeMode", "KTXanimData"}


def ktx_parse(*paths):
    """One dict per file from tests/formats/ktx_parse/read_ktx2.mjs."""
    node = shutil.which("node")
    if node is None:
        pytest.fail("node is needed to run ktx-parse (vendored in tests/formats/ktx_parse/vendor): "
                    "apt-get install nodejs (.ci/run does)")
    out = subprocess.run([node, str(KTX_PARSE / "read_ktx2.mjs"), *map(str, paths)], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    return [json.loads(line) for line in out.stdout.splitlines()]


def raw_kvd(path):
    """(keys in file order, every entry well-formed) from the bytes, per the specification."""
    b = Path(path).read_bytes()
    kvd_off, kvd_len = struct.unpack_from("<2I", b, 56)
    keys, pos, ok = [], kvd_off, True
    while pos < kvd_off + kvd_len:
        n = struct.unpack_from("<I", b, pos)[0]
        entry = b[pos + 4: pos + 4 + n]
        key, sep, value = entry.partition(b"\0")
        ok &= bool(sep) and value.endswith(b"\0") and b"\0" not in value[:-1]
        keys.append(key)
        end = pos + 4 + n
        pad = (-end) % 4
        ok &= b[end: end + pad] == b"\0" * pad
        pos = end + pad
    return keys, ok and pos == kvd_off + kvd_len


@pytest.fixture(scope="module")
def written(canyon_probe_set, tmp_path_factory):
    return write_probe_set(tmp_path_factory.mktemp("ktx") / "set", canyon_probe_set, writers=["ktx2", "webgl2"])


def test_probe_set_files_pass_an_independent_reader_and_the_spec_rules(written, canyon_probe_set):
    ps = canyon_probe_set
    probes, sky, atlas = ktx_parse(written / "probes.ktx2", written / "sky.ktx2", written / "probes_atlas.ktx2")
    layers, n, k = ps.layer_count, ps.manifest.resolution, len(ps.levels)
    lay = face_atlas_layout(n, k)
    assert (probes["vkFormat"], probes["faceCount"], probes["layerCount"], probes["levelCount"]) == (97, 6, layers, k)
    assert (sky["vkFormat"], sky["faceCount"], sky["layerCount"]) == (109, 6, 0)
    assert (atlas["vkFormat"], atlas["faceCount"], atlas["layerCount"], atlas["levelCount"]) == (97, 1, 6 * layers, 1)
    assert (atlas["pixelWidth"], atlas["pixelHeight"], atlas["pixelDepth"]) == (lay.width, lay.height, 0)
    for f, name in ((probes, "probes.ktx2"), (sky, "sky.ktx2"), (atlas, "probes_atlas.ktx2")):
        assert set(f["keyValue"]) <= SPEC_KEYS, f"{name}: custom keys {set(f['keyValue']) - SPEC_KEYS} (warning 7010)"
        assert f["keyValue"]["KTXorientation"] == "rd" and f["keyValue"]["KTXwriter"].startswith("envcap ")
        assert f["rewriteIdentical"], f"{name}: ktx-parse writes the parsed container to other bytes"
        keys, well_formed = raw_kvd(written / name)
        assert well_formed and keys == sorted(keys), name
        [dfd] = f["dfd"]
        assert (dfd["colorModel"], dfd["colorPrimaries"], dfd["transferFunction"]) == (1, 1, 1)
        assert dfd["flags"] == (0 if f is sky else 1)                       # premultiplied probes
        assert [s["channelType"] & 0x0F for s in dfd["samples"]] == [0, 1, 2, 15]
    # the texels ktx-parse reads are the probe set's, bit for bit
    for k_, lv in enumerate(probes["levels"]):
        assert lv["sha256"] == hashlib.sha256(np.asarray(ps.levels[k_], "<f2").tobytes()).hexdigest()
    want = face_atlas([np.asarray(a) for a in ps.levels], np.float16).astype("<f2").tobytes()
    assert atlas["levels"][0]["sha256"] == hashlib.sha256(want).hexdigest()


def test_custom_keys_are_what_the_reader_reports():
    # Control: a custom key is visible to the independent reader (the check above can fail): a chain
    # written by `envcap prefilter` before issue 19 carried the lobe ladder as `envcap.lobes`.
    [f] = ktx_parse(DATA / "chain_before_issue19.ktx2")
    assert set(f["keyValue"]) - SPEC_KEYS == {"envcap.lobes"} and f["rewriteIdentical"]
