"""`envcap prefilter` end to end on real small EXR files (cube env map and lat-long), through the
real CLI entry point: outputs read back with the EXR/KTX2 readers, levels checked against the
float64 exact reference, bad inputs give one-line errors and leave nothing behind."""

import json
import subprocess
import sys

import numpy as np
import OpenEXR

from envcap.core import cube as cm
from envcap.core.color import luminance
from envcap.formats.exr_cube import read_exr_cube, write_exr_cube
from envcap.formats.ktx2 import read_ktx2
from envcap.core.lobes import LobeLadder
from envcap.prefilter import convolve_exact


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "envcap", *map(str, args)], capture_output=True, text=True, timeout=120)


def _cube(n):
    d = cm.texel_directions(n)
    rgb = np.stack([1 + d[..., 0] ** 2, 2 + d[..., 1], 1.5 + np.sign(d[..., 2])], -1) * 100
    rgba = np.concatenate([rgb, (d[..., 1:2] < 0.2).astype(np.float64)], -1)
    f, r, c = cm.direction_to_texel(np.array([0.3, 0.8, 0.5]), n)
    rgba[f, r, c, :3] = 1e6  # a small sun: forces float32 EXR levels
    return rgba.astype(np.float32)


def test_exr_cube_to_chain(tmp_path):
    src = _cube(16)
    write_exr_cube(tmp_path / "env.exr", src, half=False)
    out = tmp_path / "chain"
    r = _cli("prefilter", tmp_path / "env.exr", "--out", out)
    assert r.returncode == 0, r.stderr
    man = json.loads((out / "chain.json").read_text())
    lad = LobeLadder.from_manifest(man["lobes"])
    assert man["sizes"] == [16, 8, 4, 2, 1] and man["input_kind"] == "exr-cube"
    assert set(man["timings_s"]) == {"read", "prefilter", "write"}
    levels, _ = read_ktx2(out / "chain.ktx2")
    assert [lv.shape for lv in levels] == [(6, s, s, 4) for s in lad.sizes]
    np.testing.assert_array_equal(levels[0], src)
    for k in range(1, lad.levels):
        exact = convolve_exact(src.astype(np.float64), lad.powers[k], lad.sizes[k])
        np.testing.assert_allclose(levels[k], exact, rtol=1e-3, atol=1e-3 * np.abs(exact[..., :3]).max())
        exr, _ = read_exr_cube(out / f"level_{k:02d}.exr")
        np.testing.assert_allclose(exr, levels[k], rtol=1e-3)  # half when every value fits
    exr0, _ = read_exr_cube(out / "level_00.exr")
    np.testing.assert_array_equal(exr0, src)  # the 1e6 sun does not fit half: float32


def test_latlong_and_size(tmp_path):
    h, w = 32, 64
    y = (np.arange(h) + 0.5) / h
    img = np.zeros((h, w, 3), np.float32)
    img[...] = (1.0 + 3.0 * (y < 0.5))[:, None, None]  # bright upper hemisphere, dim lower
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": img}).write(str(tmp_path / "ll.exr"))
    r = _cli("prefilter", tmp_path / "ll.exr", "--out", tmp_path / "o", "--size", 8, "--quality", "fast")
    assert r.returncode == 0, r.stderr
    man = json.loads((tmp_path / "o" / "chain.json").read_text())
    assert man["sizes"] == [8, 4, 2, 1] and man["input_kind"] == "latlong" and man["quality"] == "fast"
    levels, _ = read_ktx2(tmp_path / "o" / "chain.ktx2")
    # the widest level: up and down directions see mostly the bright / dim hemisphere
    top = luminance(levels[-1][2, 0, 0])
    bottom = luminance(levels[-1][3, 0, 0])
    assert 2.5 < top < 4.0 and 1.0 < bottom < 2.5
    np.testing.assert_allclose(levels[-1][..., 3], 1.0, rtol=1e-5)


def test_bad_inputs_one_line_errors_and_nothing_written(tmp_path):
    out = tmp_path / "o"
    r = _cli("prefilter", tmp_path / "missing.exr", "--out", out)
    assert r.returncode == 2 and r.stderr.startswith("envcap: error:") and "missing.exr" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    (tmp_path / "junk.exr").write_bytes(b"not an image at all")
    r = _cli("prefilter", tmp_path / "junk.exr", "--out", out)
    assert r.returncode == 2 and "neither" in r.stderr
    src = _cube(8)
    write_exr_cube(tmp_path / "env.exr", src, half=False)
    for size in (0, 3, 16):
        r = _cli("prefilter", tmp_path / "env.exr", "--out", out, "--size", size)
        assert r.returncode == 2 and "--size" in r.stderr, (size, r.stderr)
    assert not out.exists()


def test_nan_texels_rejected(tmp_path):
    src = _cube(8)
    img_path = tmp_path / "nan.exr"
    write_exr_cube(img_path, src, half=False)
    # poke NaNs into the file through the EXR API (write_exr_cube itself refuses NaN)
    with OpenEXR.File(str(img_path)) as f:
        hdr = dict(f.header())
        rgba = f.channels()["RGBA"].pixels.copy()
    rgba[3, 2, 0] = np.nan
    OpenEXR.File(hdr, {"RGBA": rgba}).write(str(img_path))
    r = _cli("prefilter", img_path, "--out", tmp_path / "o")
    assert r.returncode == 2 and ("NaN" in r.stderr) and not (tmp_path / "o").exists()
