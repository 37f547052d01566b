"""The EXR cube door for input radiance (``read_exr_cube``, ``envcap prefilter``).

Issue 9 regressions, old -> new behaviour:
* a cube EXR with negative texels was accepted (``envcap prefilter`` gave level 1 = -11.1) -> rejected,
  one line with the count, exit 2, no output;
* NaN/Inf texels were rejected without a count -> the count is named;
* a 40-byte or truncated EXR gave a 4-line error (plus the OpenEXR library's own lines on
  stdout/stderr) -> one line naming the file;
* a lat-long EXR was read whole by the cube reader before being told apart (twice the image in
  memory) -> the header is read first.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from envcap.formats.exr_cube import ExrDataError, read_exr_cube, write_exr_cube

REPO = Path(__file__).resolve().parents[2]


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "envcap", *map(str, args)], capture_output=True, text=True,
                          timeout=120, cwd=REPO)


def _cube_file(path, n=4, edit=None):
    # Written with the OpenEXR binding itself (envcap's writer refuses NaN); the face order and
    # orientation do not matter for counts.
    rgba = np.ones((6, n, n, 4), np.float32)
    if edit:
        edit(rgba)
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_CUBE}
    OpenEXR.File(hdr, {"RGBA": rgba.reshape(6 * n, n, 4)}).write(str(path))
    return rgba


def test_negative_radiance_is_rejected_with_its_count(tmp_path):
    def neg(a):
        a[0, 0, 0, 0] = -100.0
        a[3, 1, 2, 2] = -1e-3
        a[5, 3, 3, 3] = -7.0  # alpha: not radiance, allowed
    _cube_file(tmp_path / "neg.exr", edit=neg)
    with pytest.raises(ExrDataError, match=r"neg.exr: 2 texel\(s\) of 96 have negative R, G or B .*smallest -100"):
        read_exr_cube(tmp_path / "neg.exr")



def test_nan_and_inf_texels_are_counted(tmp_path):
    def bad(a):
        a[1, 0, 0, 1] = np.nan
        a[2, 2, 2, 3] = np.inf
    _cube_file(tmp_path / "nan.exr", edit=bad)
    with pytest.raises(ExrDataError, match=r"nan.exr: RGBA holds NaN or Inf in 2 texel\(s\) of 96"):
        read_exr_cube(tmp_path / "nan.exr")


@pytest.mark.parametrize("keep", [40, "half", "two_thirds"])
def test_truncated_exr_is_one_line_naming_the_file_and_nothing_else_printed(tmp_path, capfd, keep):
    _cube_file(tmp_path / "ok.exr", n=64, edit=lambda a: a.__setitem__(..., np.random.default_rng(0).random(a.shape)))
    data = (tmp_path / "ok.exr").read_bytes()
    cut = {40: 40, "half": len(data) // 2, "two_thirds": len(data) * 2 // 3}[keep]
    (tmp_path / "cut.exr").write_bytes(data[:cut])
    with pytest.raises(ExrDataError) as e:
        read_exr_cube(tmp_path / "cut.exr")
    assert str(e.value).startswith(f"{tmp_path / 'cut.exr'}: truncated or corrupt OpenEXR file")
    assert "\n" not in str(e.value)
    out = capfd.readouterr()
    assert out.out == "" and out.err == "", out  # the library's own messages are in the error, not printed


def test_a_latlong_exr_is_told_apart_from_its_header(tmp_path):
    img = np.ones((8, 16, 3), np.float32)
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_LATLONG}
    OpenEXR.File(hdr, {"RGB": img}).write(str(tmp_path / "ll.exr"))
    with pytest.raises(ValueError, match="not a cube environment map") as e:
        read_exr_cube(tmp_path / "ll.exr")
    assert not isinstance(e.value, ExrDataError)  # another reader (lat-long) may take it


@pytest.mark.parametrize("case", ["negative", "nan", "truncated", "tiny"])
def test_prefilter_rejects_bad_cube_inputs_in_one_line_exit_2_no_output(tmp_path, case):
    src = tmp_path / "in.exr"
    if case in ("negative", "nan"):
        value = -11.0 if case == "negative" else np.nan
        _cube_file(src, n=8, edit=lambda a: a.__setitem__((2, 3, 4, 1), value))
    else:
        _cube_file(tmp_path / "ok.exr", n=32)
        data = (tmp_path / "ok.exr").read_bytes()
        src.write_bytes(data[:40] if case == "tiny" else data[: len(data) // 2])
    r = _cli("prefilter", src, "--out", tmp_path / "o", "--quality", "fast")
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stdout + r.stderr
    assert lines[0].startswith("envcap: error: ") and "in.exr" in lines[0]
    words = {"negative": "1 texel(s) of 384 have negative", "nan": "NaN or Inf in 1 texel(s)",
             "truncated": "truncated or corrupt", "tiny": "truncated or corrupt"}[case]
    assert words in lines[0], lines[0]
    assert not (tmp_path / "o").exists()
