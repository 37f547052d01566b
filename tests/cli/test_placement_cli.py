"""``envcap capture --placement NAME --probes-per-street N`` (docs/placement.md): bad options are
one line, exit 2 and leave nothing; the default capture is unchanged (no ``placement`` entry)."""

import json

import pytest

from envcap.cli import main


@pytest.mark.parametrize("args,msg", [
    (["--placement", "nope"], "unknown placement strategy 'nope'; known: uniform, density, min_error"),
    (["--probes-per-street", "2.5"], "--probes-per-street must be a whole number of probes >= 1, got '2.5'"),
    (["--probes-per-street", "0"], "--probes-per-street must be a whole number of probes >= 1, got '0'"),
    (["--probes-per-street", "3", "--spacing", "4"], "--spacing and --probes-per-street both given: give one"),
    (["--probes-per-street", "1000000000"], "1000000000 probes per street on 1 street(s) (a bake of ~1,000,000,000 "
                                            "probes at 8^2 per face: peak memory"),
    (["--placement", "density", "--workers", "2"], "--placement and --probes-per-street are for one scene's probe set"),
])
def test_bad_placement_options_are_one_line_and_leave_nothing(tmp_path, capsys, args, msg):
    out = tmp_path / "set"
    assert main(["capture", "canyon", "--out", str(out), "--resolution", "8", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("envcap: error: ") and msg in err[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_uniform_per_street_count_and_the_default(tmp_path, capsys):
    assert main(["capture", "crossing", "--out", str(tmp_path / "a"), "--resolution", "8", "--quiet",
                 "--probes-per-street", "2"]) == 0
    m = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert m["placement"] == {"strategy": "uniform", "probes_per_street": 2, "parameters": {"spacing_m": None},
                              "seconds": m["placement"]["seconds"], "streets": {}}
    # the placement's 2 per street, and the crossing's centre probe on its first street (docs/crossings.md)
    assert [[p["position"][0 if s["axis"] == "x" else 2] for p in s["probes"]] for s in m["streets"]] == \
        [[-75.0, 0.0, 75.0], [-75.0, 75.0]]
    assert main(["capture", "crossing", "--out", str(tmp_path / "b"), "--resolution", "8", "--quiet",
                 "--spacing", "100"]) == 0
    assert "placement" not in json.loads((tmp_path / "b" / "manifest.json").read_text())
