"""Issue 9: what read_probe_set refuses, naming the file, layer and level, and what it still accepts.

Old behaviour (before the fix): NaN, Inf and negative texels in ``probes.ktx2`` / ``sky.ktx2``
passed the reader (an all-NaN set failed later in ``evaluate`` naming no file), and a manifest
position of 1e300 passed the finite check and overflowed float32.  The files here are patched
byte by byte through the KTX 2.0 level index (spec section 3.9), not through envcap's reader.
"""

from __future__ import annotations

import json
import struct

import numpy as np
import OpenEXR
import pytest
from test_probeset import N, make_set

from envcap.probeset.store import read_probe_set, write_probe_set

LAYERS = 3


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    return write_probe_set(tmp_path_factory.mktemp("sets") / "set", make_set(LAYERS), previews=False)


def copy_set(written, tmp_path):
    dst = tmp_path / "set"
    dst.mkdir(parents=True)
    for p in written.rglob("*"):
        if p.is_file():
            (dst / p.relative_to(written)).parent.mkdir(parents=True, exist_ok=True)
            (dst / p.relative_to(written)).write_bytes(p.read_bytes())
    return dst


def patch_texel(path, level: int, layer: int, texel: int, component: int, value: float, *, half: bool,
                layered: bool, count: int = 1) -> None:
    """Set ``component`` of ``count`` texels from flat texel ``texel`` of face-set ``layer`` at ``level``."""
    data = bytearray(path.read_bytes())
    offset = struct.unpack_from("<Q", data, 80 + 24 * level)[0]  # levelIndex[level].byteOffset
    size = 2 if half else 4
    nk = max(1, N >> level)
    per_layer = 6 * nk * nk * 4 * size
    base = offset + (layer * per_layer if layered else 0)
    for t in range(texel, texel + count):
        struct.pack_into("<e" if half else "<f", data, base + (4 * t + component) * size, value)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
def test_nonfinite_probe_texels_name_file_layer_and_level(written, tmp_path, value):
    root = copy_set(written, tmp_path)
    patch_texel(root / "probes.ktx2", level=2, layer=1, texel=5, component=0, value=value, half=True, layered=True,
                count=3)
    with pytest.raises(ValueError, match=r"probes\.ktx2: layer 1, level 2: 3 of 24 texels are NaN/Inf "
                                         r"\(3 in all, in 1 layer\(s\)\)"):
        read_probe_set(root)


def test_an_all_nan_set_fails_at_read_naming_the_file(written, tmp_path):
    root = copy_set(written, tmp_path)
    for k in range(4):
        nk = max(1, N >> k)
        for layer in range(LAYERS):
            for c in range(4):
                patch_texel(root / "probes.ktx2", k, layer, 0, c, float("nan"), half=True, layered=True,
                            count=6 * nk * nk)
    total = LAYERS * sum(6 * max(1, N >> k) ** 2 for k in range(4))
    with pytest.raises(ValueError, match=rf"probes\.ktx2: layer 0, level 0: {6 * N * N} of {6 * N * N} texels are "
                                         rf"NaN/Inf \({total} in all, in {LAYERS} layer"):
        read_probe_set(root)


def test_negative_radiance_and_alpha_past_one_are_refused(written, tmp_path):
    root = copy_set(written, tmp_path)
    patch_texel(root / "probes.ktx2", 0, 2, 7, 1, -0.5, half=True, layered=True)
    with pytest.raises(ValueError, match=r"probes\.ktx2: layer 2, level 0: 1 of 384 texels have negative R, G or B "
                                         r"\(radiance must be >= 0\) \(1 in all, in 1 layer\(s\); smallest -0\.5\)"):
        read_probe_set(root)
    root = copy_set(written, tmp_path / "b")
    patch_texel(root / "probes.ktx2", 1, 0, 0, 3, 1.5, half=True, layered=True)
    with pytest.raises(ValueError, match=r"probes\.ktx2: layer 0, level 1: 1 of 96 texels have alpha outside \[0, 1\]"):
        read_probe_set(root)


def test_alpha_one_half_float_step_above_one_is_rounding_and_accepted(written, tmp_path):
    root = copy_set(written, tmp_path)
    step = float(np.spacing(np.float16(1.0)))  # 2^-10: the next half float above 1
    patch_texel(root / "probes.ktx2", 1, 0, 0, 3, 1.0 + step, half=True, layered=True)
    assert read_probe_set(root).levels[1][0, 0, 0, 0, 3] == np.float32(1.0 + step)
    patch_texel(root / "probes.ktx2", 1, 0, 0, 3, 1.0 + 2 * step, half=True, layered=True)
    with pytest.raises(ValueError, match="alpha outside"):
        read_probe_set(root)


@pytest.mark.parametrize("value, words", [(float("nan"), "are NaN/Inf"), (-3.0, "have negative R, G or B")])
def test_sky_texels_are_checked_too(written, tmp_path, value, words):
    root = copy_set(written, tmp_path)
    patch_texel(root / "sky.ktx2", 3, 0, 2, 2, value, half=False, layered=False)
    with pytest.raises(ValueError, match=rf"sky\.ktx2: level 3: 1 of 6 texels {words}"):
        read_probe_set(root)


def test_negative_distance_in_an_exr_is_refused_naming_it(written, tmp_path):
    root = copy_set(written, tmp_path)
    path = root / "exr/probe_001.exr"
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = dict(f.header())
        chans = {k: np.array(c.pixels) for k, c in f.channels().items()}
    chans["Z"][3, 2] = -4.0
    OpenEXR.File(header, chans).write(str(path))
    with pytest.raises(ValueError, match=r"exr/probe_001\.exr: 1 texel\(s\) of Z \(distance\) are negative"):
        read_probe_set(root)


@pytest.mark.parametrize("edit, message", [
    (lambda m: m["streets"][0]["probes"][1]["position"].__setitem__(0, 1e300),
     r"streets\[0\]\.probes\[1\]\.position\[0\]: 1e\+300 is outside the float32 range"),
    (lambda m: m["streets"][0]["planes"].__setitem__("ground", -3.5e38),
     r"streets\[0\]\.planes\.ground: -3\.5e\+38 is outside the float32 range"),
    (lambda m: m["streets"][0].__setitem__("end", 1e39), r"streets\[0\]\.end: 1e\+39 is outside the float32 range"),
    (lambda m: m.__setitem__("probe_height", 1e300), r"probe_height: 1e\+300 is outside the float32 range"),
    (lambda m: m.__setitem__("probe_spacing", 1e-300), r"probe_spacing: must be positive .* as float32, got 1e-300"),
    (lambda m: m["levels"][1].__setitem__("lobe_power", 1e-60), r"levels\[1\]\.lobe_power: must be positive"),
    (lambda m: m["sky"]["spec"].__setitem__("turbidity", 1e300), r"sky\.spec\.turbidity: 1e\+300 is outside"),
    (lambda m: m.__setitem__("resolution", 2 ** 31), r"resolution: 2147483648 is outside the int32 range"),
])
def test_manifest_numbers_past_float32_are_refused_with_their_field(written, tmp_path, edit, message):
    root = copy_set(written, tmp_path)
    m = json.loads((root / "manifest.json").read_text())
    edit(m)
    (root / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(ValueError, match=r"manifest\.json: " + message):
        read_probe_set(root)


def test_the_largest_float32_values_still_pass(written, tmp_path):
    root = copy_set(written, tmp_path)
    m = json.loads((root / "manifest.json").read_text())
    biggest = float(np.finfo(np.float32).max)
    m["streets"][0]["probes"][0]["position"][2] = -biggest
    m["sky"]["spec"]["turbidity"] = biggest
    (root / "manifest.json").write_text(json.dumps(m))
    back = read_probe_set(root)
    assert np.isfinite(np.float32(back.manifest.streets[0].probes[0].position[2]))
