"""End to end (docs/crossings.md): ``envcap capture`` of a crossing records the crossing and its
shared centre probe; ``envcap evaluate`` on that set reports the positions inside the crossing,
looked up through it; ``--no-crossings`` gives the set without them."""

import json
from pathlib import Path

from envcap.cli import main

ROOT = Path(__file__).resolve().parents[2]


def short_crossing(tmp_path: Path) -> Path:
    """The bundled crossing with both streets cut to -40 .. 40 m (a small bake)."""
    text = (ROOT / "city_scenes/crossing.toml").read_text()
    assert text.count("start = -150.0") == 2 and text.count("end = 150.0") == 2
    p = tmp_path / "crossing.toml"
    p.write_text(text.replace("start = -150.0", "start = -40.0").replace("end = 150.0", "end = 40.0"))
    return p


def test_capture_then_evaluate_reports_the_crossing(tmp_path, capsys):
    scene = short_crossing(tmp_path)
    ps = tmp_path / "set"
    assert main(["capture", str(scene), "--out", str(ps), "--resolution", "8", "--spacing", "10", "--quiet",
                 "--no-exr", "--no-previews"]) == 0
    m = json.loads((ps / "manifest.json").read_text())
    ew, ns = m["streets"]
    assert [p["position"][0] for p in ew["probes"]] == [-35.0, -25.0, -15.0, -5.0, 0.0, 5.0, 15.0, 25.0, 35.0]   # + the centre
    assert [p["position"][2] for p in ns["probes"]] == [-35.0, -25.0, -15.0, -5.0, 5.0, 15.0, 25.0, 35.0]
    assert m["crossings"] == [{"name": "east_west+north_south", "centre": [0.0, 2.0, 0.0],
                               "streets": ["east_west", "north_south"], "probe_layer": 4}]
    out = tmp_path / "report"
    assert main(["evaluate", str(scene), "--probes", str(ps), "--out", str(out), "--positions", "8", "--resolution", "8",
                 "--lobes", "64", "--methods", "nearest,depth_refine", "--no-images", "--quiet"]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["meta"]["crossing"]["crossings"] == ["east_west+north_south"]
    assert rep["meta"]["crossing"]["crossing_lookup"] == "direction"
    inside = [r for r in rep["positions"] if r["in_crossing"]]
    # inside = in both corridors: |x| <= 6 and |z| <= 7
    assert inside and all(abs(r["position"][0]) <= 6 and abs(r["position"][2]) <= 7 for r in inside)
    assert all(r["in_crossing"] == (abs(r["position"][0]) <= 6 and abs(r["position"][2]) <= 7) for r in rep["positions"])
    assert "### Positions inside a crossing (east_west+north_south; lookup `direction`" in (out / "report.md").read_text()
    capsys.readouterr()
    assert main(["capture", str(scene), "--out", str(tmp_path / "plain"), "--resolution", "8", "--spacing", "10",
                 "--quiet", "--no-exr", "--no-previews", "--no-crossings"]) == 0
    plain = json.loads((tmp_path / "plain" / "manifest.json").read_text())
    assert "crossings" not in plain and len(plain["streets"][0]["probes"]) == 8
