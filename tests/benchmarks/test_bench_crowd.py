"""``envcap bench crowd --quick``: the table and JSON it writes (every term timed against the unlit
crowd of the same run, the GPU bytes, the renderer string)."""

import json

import numpy as np
import pytest

from envcap.benchmarks.crowd import split_triangles
from envcap.cli import main
from envcap.scene import load_scene


@pytest.mark.slow
def test_bench_crowd_quick_writes_the_table(tmp_path, capsys):
    assert main(["bench", "crowd", "--quick", "--no-paper", "--repeats", "1", "--out", str(tmp_path / "b")]) == 0
    data = json.loads((tmp_path / "b" / "crowd.json").read_text())
    assert data["renderer"] and data["renderer"] in capsys.readouterr().out
    rows = data["rows"]
    assert [r["walkers"] for r in rows] == [10, 40, 10]
    for r in rows:
        assert r["ratio_to_unlit"]["unlit"] == 1.0
        assert all(r["median_s"][v] > 0 for v in ("unlit", "probes", "self", "neighbours"))
        assert r["gpu_bytes"] > r["street_triangles"] * 3 * 4       # at least the street's indices
    assert rows[2]["gpu_bytes"] > rows[0]["gpu_bytes"]             # a bigger frame, more bytes
    assert "| walkers |" in (tmp_path / "b" / "crowd.md").read_text()


def test_split_triangles_doubles_the_street_and_keeps_its_area():
    scene = load_scene("avenue")
    split = split_triangles(scene)

    def area(m):
        p = m.positions.astype(float)[m.indices.astype(int)]
        return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()

    assert len(split.mesh.indices) == 2 * len(scene.mesh.indices)
    assert area(split.mesh) == pytest.approx(area(scene.mesh), rel=1e-6)
