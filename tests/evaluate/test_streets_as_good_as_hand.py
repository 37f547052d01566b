"""The streets ``envcap streets`` finds in the generated city's mesh file, in the scene it writes,
evaluate as well as the city's true streets set by hand (``docs/examples/generated_city_by_hand.toml``;
docs/evaluation.md, "Streets found by `envcap streets`"): per street, the parallax gain
(``nearest`` / ``planes_mip``, sun out of the sky) of the found street is at least 90 % of the hand
street's, measured at the same sweep positions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from envcap.cli import main
from envcap.core.resources import city_scenes_dir
from envcap.evaluate.run import evaluate_scene
from envcap.evaluate.sweep import Sweep, sample_positions
from envcap.probeset.bake import bake_probe_set
from envcap.scene import load_scene

CITY = city_scenes_dir() / "generated_city" / "data"
HAND = Path(__file__).resolve().parents[2] / "docs" / "examples" / "generated_city_by_hand.toml"


@pytest.fixture(scope="module")
def found(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("streets") / "found"
    frame = json.loads((CITY / "truth.json").read_text())["frame"]
    assert main(["streets", str(CITY / "city.xml"), "--up-axis", frame["up_axis"],
                 "--offset", *(str(v) for v in frame["offset"]), "--out", str(out), "--quiet"]) == 0
    return out / "scene.toml"


def test_the_hand_scene_lists_the_true_streets_in_the_order_they_are_found(found: Path) -> None:
    truth = {t["name"]: t for t in json.loads((CITY / "truth.json").read_text())["streets"]}
    hand, auto = load_scene(HAND), load_scene(found)
    assert len(hand.streets) == len(auto.streets) == len(truth)
    for h, a in zip(hand.streets, auto.streets):
        t = truth[h.name]
        assert h.width == t["width"] and h.follow_terrain == (t["district"] == "radial") == a.follow_terrain
        assert h.yaw_deg == pytest.approx(t["angle_deg"] % 180.0, abs=1e-3)
        assert a.yaw_deg == pytest.approx(h.yaw_deg, abs=0.1) and a.width == pytest.approx(h.width, abs=0.5)
        ta = np.radians(h.yaw_deg)
        normal = np.array([-np.sin(ta), np.cos(ta)])
        assert abs((np.array(a.origin_xz) - np.array(h.origin_xz)) @ normal) < 0.5, h.name   # the same centre line


def _gain_per_street(scene, probes, positions: np.ndarray, gl_ctx) -> list[float]:
    """Per street of ``scene``: mean error of ``nearest`` / that of ``planes_mip`` (w = 64, sun out
    of the sky, 16^2 truth) at ``positions``, each counted on the street that holds it."""
    res = evaluate_scene(scene, probes, positions=positions, methods=("nearest", "planes_mip"), lobe_powers=(64.0,),
                         resolution=16, ctx=gl_ctx, materials=(), keep_worst=0, floor_probes=0, sun_variants=(False,),
                         progress=False)
    names = [s.name for s in scene.streets]
    err: dict[tuple[int, str], list[float]] = {}
    for r in res.rows:
        err.setdefault((names.index(r["street"]), r["method"]), []).append(r["rel_rmse"])
    return [float(np.mean(err[i, "nearest"]) / np.mean(err[i, "planes_mip"])) for i in range(len(names))]


@pytest.mark.slow
def test_found_streets_evaluate_within_ten_percent_of_the_hand_set_ones(found: Path, gl_ctx) -> None:
    """Both probe sets at the same positions: each set's own sweep (6 per street), joined, so a
    stretch that one of them covers and the other does not counts against the other."""
    scenes = [load_scene(HAND), load_scene(found)]
    probes = [bake_probe_set(s, resolution=16, spacing=10.0, ctx=gl_ctx, progress=False) for s in scenes]
    positions = np.array([p.position for ps in probes for p in sample_positions(ps.manifest, Sweep(per_street=6))])
    hand, auto = (_gain_per_street(s, ps, positions, gl_ctx) for s, ps in zip(scenes, probes))
    worse = {i: round(a / h, 3) for i, (h, a) in enumerate(zip(hand, auto)) if a < 0.9 * h}
    assert worse == {}, f"found / hand gain below 0.9 on streets {worse} (hand {hand}, found {auto})"
