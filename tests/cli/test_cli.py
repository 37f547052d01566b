"""The envcap CLI end to end: capture writes a readable probe set; bad input is one line, exit 2."""

import json
import subprocess
import sys

import numpy as np
import pytest

from envcap.cli import main


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "envcap", *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def test_capture_writes_a_probe_set_that_reads_back(tmp_path):
    from envcap.probeset.store import read_probe_set

    out = tmp_path / "set"
    r = run_cli("capture", "imported", "--out", str(out), "--resolution", "16", "--spacing", "20", "--exr")
    assert r.returncode == 0, r.stderr
    ps = read_probe_set(out)
    m = ps.manifest
    assert m.resolution == 16 and ps.layer_count == sum(len(s.probes) for s in m.streets)
    assert [lv.size for lv in m.levels] == [16 >> k for k in range(len(ps.levels))]
    assert all(lv.lobe_power > 0 for lv in m.levels)
    for level in ps.levels:
        assert np.all(np.isfinite(level))
    assert m.sky.sun is None or np.all(np.isfinite(m.sky.sun.illuminance))
    # alpha in [0, 1] at every level, premultiplied RGB never brighter than alpha allows to be negative
    for level in ps.levels:
        a = level[..., 3]
        assert a.min() >= -1e-3 and a.max() <= 1 + 1e-3
    assert (out / "exr").is_dir() and len(list((out / "exr").glob("*.exr"))) == ps.layer_count
    assert not (out / "previews").exists()  # opt-in for capture (--previews)
    assert "progress: capture: " in r.stderr and "probes/s" in r.stderr  # progress: lines when not a terminal
    json.dumps(m.to_json(), allow_nan=False)


@pytest.mark.parametrize(
    "args, words",
    [
        (["capture", "no_such_scene", "--out", "X"], "no_such_scene"),
        (["capture", "imported", "--out", "X", "--resolution", "0"], "resolution"),
        (["capture", "imported", "--out", "X", "--spacing", "-5"], "spacing"),
        (["capture", "imported", "--out", "X", "--height", "0"], "height"),
    ],
)
def test_bad_arguments_give_one_line_and_leave_nothing(tmp_path, args, words):
    args = [a if a != "X" else str(tmp_path / "out") for a in args]
    r = run_cli(*args)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("envcap: error:") and words in lines[0], r.stderr
    assert not (tmp_path / "out").exists()
    assert list(tmp_path.iterdir()) == []


def test_help_lists_the_commands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    for cmd in ("capture", "scenes", "bench"):
        assert cmd in text


SCENE_TEMPLATE = """
name = "t"
description = "test"
effects = {effects}

[sky]
{sky}

[[streets]]
name = "s"
axis = "x"
start = -10.0
end = 10.0
width = 12.0
cross = 0.0
"""


def _write_nan_latlong(path):
    import OpenEXR

    img = np.ones((8, 16, 3), np.float32)
    img[3, 5, 1] = np.nan
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": img}).write(str(path))


@pytest.mark.parametrize(
    "effects, sky, words",
    [
        ('["sun_light", "fog"]', 'type = "uniform"\nradiance = [1.0, 1.0, 1.0]', "fog"),
        ('["sky_light"]', 'type = "latlong"\nfile = "missing.exr"', "missing.exr"),
        ('["sky_light"]', 'type = "latlong"\nfile = "nan.exr"', "NaN"),
        ('["sky_light"]', 'type = "preetham"\nturbidity = 30.0\nsun_elevation_deg = 30.0', "turbidity"),
    ],
)
def test_bad_scene_files_give_one_clear_line(tmp_path, effects, sky, words):
    _write_nan_latlong(tmp_path / "nan.exr")
    scene = tmp_path / "t.toml"
    scene.write_text(SCENE_TEMPLATE.format(effects=effects, sky=sky))
    r = run_cli("capture", str(scene), "--out", str(tmp_path / "out"), "--resolution", "8")
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and words in lines[0], r.stderr
    assert not (tmp_path / "out").exists()


def test_missing_scene_file_is_one_line(tmp_path):
    r = run_cli("capture", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "out"))
    assert r.returncode == 2 and "nope.toml" in r.stderr and "Traceback" not in r.stderr


def test_a_scene_without_sun_effects_runs_no_sun_or_shadow_pass(gl_ctx, canyon_probe_set):
    from envcap.probeset.bake import bake_probe_set
    from envcap.scene import load_scene

    scene = load_scene("avenue")  # effects: emissive_windows, sky_light
    assert "sun_light" not in scene.effects
    ps = bake_probe_set(scene, resolution=8, spacing=400.0, ctx=gl_ctx, filter_levels=False, progress=False)
    assert "shadow_map" not in ps.manifest.passes_run
    assert ps.manifest.effects == ("emissive_windows", "sky_light")
    assert "shadow_map" in canyon_probe_set.manifest.passes_run  # the canyon has a sun
