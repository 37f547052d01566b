"""Errors inside the bundled crossing's region (docs/evaluation.md, "Crossings"), sun out of the sky.

``positions MODE[,MODE...]``: ``nearest`` and ``depth_refine`` at w = 64 and 256 on 40 positions
drawn uniformly in the region (x in [-5.5, 5.5], y in [0.3, 3], z in [-6.5, 6.5] m,
``numpy.random.default_rng(7)``), per crossing lookup mode.  ``corners``: per direction class (up,
down, horizontal; truth sky or street) the share of the squared error of ``depth_refine`` at the
three positions next to a building corner, the best single probe of either street, the per-mode
totals.  The probe set is baked in memory as ``envcap evaluate crossing --bake 60 --crossings``
bakes it (64², 5 m spacing).  Run from the repository root (about 2 min per mode on 2 cores):
``PYTHONPATH=. python3 docs/images/crossing_inside.py positions direction,shared``.
"""

import sys

import numpy as np

from envcap.core import cube
from envcap.evaluate.metrics import luminance
from envcap.evaluate.predict import Predictor
from envcap.evaluate.run import PositionEvaluator, check_settings, evaluate_scene
from envcap.evaluate.sweep import positions_from_array
from envcap.evaluate.truth import TruthRenderer
from envcap.gpu.context import create_context
from envcap.probeset.bake import bake_probe_set
from envcap.runtime import methods
from envcap.runtime.crossing_lookup import probe_street
from envcap.runtime.sampling import composite
from envcap.scene import load_scene
from envcap.scene.segment import street_segment

CORNERS = np.array([[-5.57, 0.70, 4.56], [-3.34, 2.19, -5.23], [-3.14, 2.72, -4.64]])


def uniform_positions() -> np.ndarray:
    rng = np.random.default_rng(7)
    return np.c_[rng.uniform(-5.5, 5.5, 40), rng.uniform(0.3, 3.0, 40), rng.uniform(-6.5, 6.5, 40)]


def positions(scene, ps, modes):
    for mode in modes:
        res = evaluate_scene(scene, ps, positions=uniform_positions(), crossings=mode, methods=["nearest", "depth_refine"],
                             lobe_powers=[64.0, 256.0], sun_variants=(False,), materials=(), keep_worst=0,
                             floor_probes=0, progress=False)
        for w in (64, 256):
            e = {m: np.mean([r["rel_rmse"] for r in res.rows if r["method"] == m and r["lobe_power"] == w
                             and r["in_crossing"]]) for m in ("nearest", "depth_refine")}
            print(f"{mode} w={w}: nearest {e['nearest']:.3f} depth_refine {e['depth_refine']:.3f} "
                  f"({e['nearest'] / e['depth_refine']:.2f}x)")


def corners(scene, ps, w=64.0):
    ctx = create_context()
    settings = check_settings(scene, ps, ["depth_refine"], [w], (False,), None)
    truth = TruthRenderer(scene, settings.resolution, ctx, quality=settings.quality)
    preds = {mode: Predictor(ps, sky=truth.sky, ctx=ctx, crossings=mode) for mode in ("shared", "direction")}
    pe = PositionEvaluator(settings, truth, preds["shared"])
    dr = methods.get("depth_refine")
    for ep in positions_from_array(ps.manifest, CORNERS):
        at = pe.truth_at(ep)
        part = at.parts[w]
        m = part["street"].shape[1]
        yt = luminance(composite(part["street"], part["sky_nosun"]))
        d = pe.directions(m, ep.yaw_deg)
        ws = np.full(len(d), w)
        sky = pe.predicted_sky(m, w, False, ep.yaw_deg).reshape(6, m, m, -1)
        om = cube.texel_solid_angles(m)
        norm = np.sqrt(np.sum(om * yt ** 2))
        x = np.array(ep.position)

        def err2(st):
            return om * (luminance(composite(st.reshape(6, m, m, 4), sky)) - yt) ** 2

        e = err2(preds["shared"].street_rgba("depth_refine", ep.street, x, d, ws))
        dd = d.reshape(6, m, m, 3)
        up, down = dd[..., 1] > 0.3, dd[..., 1] < -0.3
        sky_t = part["street"][..., 3] < 0.5
        single = []
        for sp in preds["shared"].streets.values():
            rs = sp.runtime_street(dr.planes)
            for layer in rs.layers:
                single.append((np.sqrt(err2(dr(preds["shared"].chains, probe_street(rs, int(layer)), x, d, ws)).sum()) / norm,
                               sp.name, rs.positions[rs.layers == layer][0].round(2).tolist()))
        best = min(single)
        e_dir = np.sqrt(err2(preds["direction"].street_rgba("depth_refine", ep.street, x, d, ws)).sum()) / norm
        t = e.sum()
        print(f"{np.round(x, 2).tolist()}: shared {np.sqrt(t) / norm:.3f}  up {e[up].sum() / t:.0%}  down "
              f"{e[down].sum() / t:.0%}  horizontal {e[~up & ~down].sum() / t:.0%}  truth sky {e[sky_t].sum() / t:.0%}  "
              f"best single probe {best[0]:.3f} ({best[1]}, {best[2]})  direction {e_dir:.3f}")


if __name__ == "__main__":
    scene = street_segment(load_scene("crossing"), 60.0)
    ps = bake_probe_set(scene, resolution=64, spacing=5.0, crossings=True, progress=False)
    if sys.argv[1:2] == ["corners"]:
        corners(scene, ps)
    else:
        positions(scene, ps, sys.argv[2].split(",") if len(sys.argv) > 2 else ["direction", "shared"])
