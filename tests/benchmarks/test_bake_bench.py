"""``envcap bench bake`` end to end on a tiny bake: every run, stage and ratio is reported, and
the fast path's levels stay within 0.5 % of the exact reference."""

from __future__ import annotations

import argparse
import json

from envcap.benchmarks import bake


def test_bench_bake_reports_runs_stages_and_errors(tmp_path):
    p = argparse.ArgumentParser()
    bake.add_arguments(p)
    args = p.parse_args(["--out", str(tmp_path / "b"), "--sizes", "4", "--spacing", "150", "--samples", "8",
                         "--error-probes", "1"])
    assert bake.run(args) == 0
    result = json.loads((tmp_path / "b" / "bake.json").read_text())
    (rec,) = result["sizes"]
    assert rec["size"] == 4 and rec["probes"] >= 2
    assert set(rec["runs"]) == {"before", "after", "after_files"}
    assert {"sky", "capture", "prefilter", "planes", "write ktx2", "write exr", "write previews"} <= set(rec["runs"]["before"]["stages"])
    assert "write exr" not in rec["runs"]["after"]["stages"] and "write files" in rec["runs"]["after_files"]["stages"]
    for errors in rec["prefilter_error"]["rel_rmse_per_level"].values():
        assert len(errors) == 2 and max(errors) < 5e-3
    assert (tmp_path / "b" / "after_files_4" / "exr").is_dir() and not (tmp_path / "b" / "after_4" / "exr").exists()
    assert "| 6x4^2" in (tmp_path / "b" / "bake.md").read_text()
    # the floor: the capture alone and without shading over the set's probes, the filter per level
    fl = rec["floor"]
    assert fl["probes"] == rec["probes"]
    for what in ("capture", "geometry_only"):
        assert fl[what]["ms_per_probe"] > 0 and fl[what]["render_ms_per_probe"] <= fl[what]["ms_per_probe"]
    assert "shadow_map" in fl["capture"]["set_passes_s"] and not fl["geometry_only"]["set_passes_s"]
    pf = fl["prefilter"]
    assert set(pf["levels"]) == {"1", "2"} and pf["probes"] == min(8, rec["probes"])
    assert sum(v["cpu_ms_per_probe"] for v in pf["levels"].values()) <= pf["cpu_ms_per_probe"] + 0.02
    g = fl["goal"]
    assert abs(g["capture_alone_share_of_wall_budget"] - fl["capture"]["ms_per_probe"] * 10 / 1000) < 1e-3
    assert "| 4 | capture (" in (tmp_path / "b" / "bake.md").read_text()
    # --sky-visibility: interleaved pairs without / with the writer, their ratio, the moments' error
    sv = rec["sky_visibility"]
    assert len(sv["pairs"]) == 2 and sv["goal_ratio"] == 2.0
    for pair in sv["pairs"]:
        assert pair["with"]["writer_s"] > 0 and pair["without"]["writer_s"] == 0
        assert pair["ratio_wall"] == round(pair["with"]["wall_s"] / pair["without"]["wall_s"], 3)
    assert sv["ratio_wall_max"] >= sv["ratio_wall_median"] > 0
    rungs = sv["error"]["harmonics"]
    assert [e["rung"] for e in rungs] == [0, 1, 2, 3]          # 4^2: one level, rung 0 unfiltered
    assert rungs[0]["max_abs"] < 1e-7 and 0 < max(e["max_abs"] for e in rungs) < 1e-3   # rung 0: alpha Y in float32
    assert "--sky-visibility" in (tmp_path / "b" / "bake.md").read_text()
