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
