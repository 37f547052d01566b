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
    from envcap.probeset import read_probe_set

    out = tmp_path / "set"
    r = run_cli("capture", "imported", "--out", str(out), "--resolution", "16", "--spacing", "20", "--no-previews")
    assert r.returncode == 0, r.stderr
    ps = read_probe_set(out)
    m = ps.manifest
    assert m["resolution"] == 16 and ps.layer_count == sum(len(s["probes"]) for s in m["streets"])
    assert [lv["size"] for lv in m["levels"]] == [16 >> k for k in range(len(ps.levels))]
    assert all(lv["lobe_power"] > 0 for lv in m["levels"])
    for level in ps.levels:
        assert np.all(np.isfinite(level))
    assert m["sky"]["sun"] is None or np.all(np.isfinite(m["sky"]["sun"]["illuminance"]))
    # alpha in [0, 1] at every level, premultiplied RGB never brighter than alpha allows to be negative
    for level in ps.levels:
        a = level[..., 3]
        assert a.min() >= -1e-3 and a.max() <= 1 + 1e-3
    assert (out / "exr").is_dir() and len(list((out / "exr").glob("*.exr"))) == ps.layer_count
    json.dumps(m)


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
