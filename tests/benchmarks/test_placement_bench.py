"""``envcap bench placement`` at its smallest: every file it promises, uniform's ratio 1, every
strategy scored on the same positions, the errors equal to ``envcap evaluate``'s own."""

import csv
import json

import numpy as np
import pytest

from envcap.cli import main
from envcap.evaluate.run import evaluate_scene
from envcap.evaluate.sweep import Sweep
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.placement_table import PlacementTable
from envcap.scene import load_scene
from envcap.scene.segment import street_segment


@pytest.mark.slow
def test_bench_placement_smallest(tmp_path, capsys, gl_ctx):
    out = tmp_path / "bench"
    assert main(["bench", "placement", "--out", str(out), "--scenes", "crossing", "--strategies", "uniform,density",
                 "--counts", "2", "--positions", "2", "--length", "20", "--resolution", "16",
                 "--methods", "nearest,depth_refine", "--powers", "64", "--figure-street", "crossing:north_south"]) == 0
    printed = capsys.readouterr().out
    assert "goal (mean over scenes and powers of error / uniform's, depth_refine): density" in printed
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "placement.csv", "placement.json", "placement_pareto.png", "placement_street.png"]
    doc = json.loads((out / "placement.json").read_text())
    rows = list(csv.DictReader((out / "placement.csv").open()))
    assert len(rows) == len(doc["rows"]) == 2 * 2            # strategies x methods (one count, one power)
    assert all(float(r["ratio_to_uniform"]) == 1.0 and float(r["ratio_ci95"]) == 0.0 for r in rows if r["strategy"] == "uniform")
    assert [len(p) for p in doc["per_position"]] == [2 * 2] * 4              # positions x streets, every row
    for r, each in zip(doc["rows"], doc["per_position"]):
        assert np.mean(each) == pytest.approx(r["error"], rel=1e-12)
    # independent: the uniform row is envcap evaluate's error for the same bake at the same positions
    scene = street_segment(load_scene("crossing"), 20.0)
    along = doc["scenes"]["crossing"]["placed"]["uniform"]["along"]["2"]
    ps = bake_probe_set(scene, resolution=16, quality="composed", ctx=gl_ctx, along=along,
                        placement=PlacementTable("uniform", 2), progress=False)
    res = evaluate_scene(scene, ps, sweep=Sweep(per_street=2, seed=5), methods=["depth_refine"], lobe_powers=(64.0,), resolution=64,
                         ctx=gl_ctx, materials=(), keep_worst=0, floor_probes=0, sun_variants=(False,), progress=False)
    got = next(r["error"] for r in doc["rows"] if r["strategy"] == "uniform" and r["method"] == "depth_refine")
    assert got == pytest.approx(res.error("depth_refine", 64.0, sun=False), rel=1e-12)
    for name in ("east_west", "north_south"):
        assert along[name] == [-5.0, 5.0]
