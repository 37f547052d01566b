"""envcap.core.budget: bounds before work, against /proc/meminfo read here and hand-computed sizes."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from envcap.core import budget
from envcap.core.budget import BudgetError, check_bytes, check_count, format_bytes, parse_bytes
from envcap.core.latlong import latlong_to_cube, load_latlong

GIB = 1 << 30


def test_parse_and_format_bytes():
    assert parse_bytes("1500000") == 1_500_000
    assert parse_bytes("512M") == 512 * (1 << 20)
    assert parse_bytes("64G") == 64 * GIB
    assert parse_bytes(" 1.5T ") == int(1.5 * (1 << 40))
    assert parse_bytes("2GiB") == 2 * GIB and parse_bytes("3k") == 3072
    for bad in ("", "-1G", "lots", "1X", "inf", "1e999"):
        with pytest.raises(ValueError, match="ENVCAP_MAX_MEMORY"):
            parse_bytes(bad)
    assert format_bytes(40) == "40 B"
    assert format_bytes(1.5 * GIB) == "1.5 GiB"
    assert format_bytes(74.5 * GIB) == "74.5 GiB"
    assert format_bytes(16384 * 8192 * 12) == "1.5 GiB"


def test_check_bytes_message_names_what_cost_limit_and_option(monkeypatch):
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "1G")
    assert check_bytes("probe array", GIB, option="--resolution") == GIB  # at the limit: allowed
    with pytest.raises(BudgetError) as e:
        check_bytes("probe array of 2000000 probes", 3 * GIB, option="--spacing")
    msg = str(e.value)
    assert "\n" not in msg and isinstance(e.value, ValueError)
    for words in ("probe array of 2000000 probes", "3 GiB", "1 GiB", "ENVCAP_MAX_MEMORY", "--spacing"):
        assert words in msg, msg
    with pytest.raises(BudgetError, match="--resolution"):
        check_bytes("cube", float("inf"), option="--resolution")
    with pytest.raises(ValueError, match="finite"):
        check_bytes("cube", float("nan"), option="--resolution")
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "not-a-size")
    with pytest.raises(ValueError, match="ENVCAP_MAX_MEMORY='not-a-size'"):
        check_bytes("cube", 1, option="--size")


def test_default_limit_is_memavailable(monkeypatch):
    monkeypatch.delenv("ENVCAP_MAX_MEMORY", raising=False)
    meminfo = Path("/proc/meminfo")
    if not meminfo.exists():
        pytest.skip("no /proc/meminfo")
    kib = next(int(ln.split()[1]) for ln in meminfo.read_text().splitlines() if ln.startswith("MemAvailable:"))
    limit, source = budget.memory_limit()
    assert source.startswith("available memory") and abs(limit - kib * 1024) < 0.2 * kib * 1024
    with pytest.raises(BudgetError, match="MemAvailable"):
        check_bytes("a twice-the-machine array", 2 * kib * 1024, option="--size")
    assert check_bytes("a small array", 1 << 20, option="--size") == 1 << 20


def test_check_count():
    assert check_count("probes", 1000, 1000, option="--spacing") == 1000
    with pytest.raises(BudgetError) as e:
        check_count("probes", 2e10, 1_000_000, option="--spacing")
    assert str(e.value) == "probes: 20,000,000,000 asked, more than the limit of 1,000,000; change --spacing"
    for bad in (float("nan"), float("inf"), 1e300):
        with pytest.raises(BudgetError, match="--spacing"):
            check_count("probes", bad, 10, option="--spacing")


def _write_latlong(path, h):
    img = np.ones((h, 2 * h, 3), np.float32)
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": img}).write(str(path))


def test_latlong_image_and_cube_are_checked_before_allocating(tmp_path, monkeypatch):
    # 256 x 512 pixels: the float32 RGB image (12 B a pixel) plus one band of reading temporaries
    # (40 B a pixel; here the whole image is one band) = 52 B x 131072 = 6.5 MiB.
    _write_latlong(tmp_path / "sky.exr", 256)
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "6M")
    with pytest.raises(BudgetError, match=r"sky.exr \(512x256 RGB float32\): needs 6.5 MiB, more than the 6 MiB"):
        load_latlong(tmp_path / "sky.exr")
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "64M")
    img = load_latlong(tmp_path / "sky.exr")
    # A 2048^2 cube of 3 float32 channels is 288 MiB before any texel is computed.
    with pytest.raises(BudgetError, match=r"512x256 to a cube of 6x2048x2048 texels: needs \d{3} MiB, more than the "
                                          r"64 MiB memory limit \(ENVCAP_MAX_MEMORY\); change the cube face size"):
        latlong_to_cube(img, 2048)


def test_cli_prefilter_too_large_cube_is_one_line_exit_2(tmp_path):
    _write_latlong(tmp_path / "sky.exr", 16)
    env = dict(os.environ, ENVCAP_MAX_MEMORY="50M")
    r = subprocess.run([sys.executable, "-m", "envcap", "prefilter", str(tmp_path / "sky.exr"), "--out",
                        str(tmp_path / "o"), "--size", "2048"], capture_output=True, text=True, timeout=120,
                       env=env, cwd=Path(__file__).resolve().parents[2])
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "needs" in lines[0] and "--size" in lines[0] and "ENVCAP_MAX_MEMORY" in lines[0]
    assert not (tmp_path / "o").exists()
