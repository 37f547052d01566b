"""Parallax evaluation: the evaluator checked against independent references.

* the truth filter against the float64 brute-force lobe integral (``convolve_exact``);
* a probe evaluated at its own capture position: zero error for every method (mirror and the
  ladder's first lobe level; float16 storage through a written probe set);
* the ``planes`` scene (every visible point on one of the three planes): the three-plane
  prediction converges to the truth as the probe resolution grows, nearest does not;
* depth reprojection against a hand-derived single-plane case;
* the Predictor's blend / planes_mip (local probes) against the runtime twin
  ``envcap.runtime.sampling.sample_street`` (whole street);
* positions, bad inputs, CLI errors, atomic reports.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from envcap.cli import main
from envcap.core import cube
from envcap.evaluate.predict import Predictor
from envcap.evaluate.report import write_report
from envcap.evaluate.run import evaluate_scene
from envcap.evaluate.sweep import Sweep, sample_positions
from envcap.evaluate.truth import filter_truth, truth_grid_size
from envcap.prefilter import convolve_exact
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.store import read_probe_set, write_probe_set
from envcap.runtime.chains import ProbeChains
from envcap.runtime.methods import METHODS
from envcap.runtime.methods.depth_reproject import depth_reproject
from envcap.runtime.parallax import parallax
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet
from envcap.scene import load_scene
from envcap.scene.segment import street_segment


@pytest.fixture(scope="module")
def planes_scene():
    return street_segment(load_scene("planes"), 20.0)


@pytest.fixture(scope="module")
def planes_probes(planes_scene, gl_ctx):
    return bake_probe_set(planes_scene, resolution=32, spacing=10.0, ctx=gl_ctx, progress=False)


def _smooth_cube(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = cube.texel_directions(n)
    out = np.empty((6, n, n, 4))
    for c in range(4):
        a = rng.normal(size=3)
        out[..., c] = 1.0 + 0.5 * np.sin(3.0 * d @ a) + (d[..., 1] > 0.3) * (c + 1.0)
    return out.astype(np.float32)


@pytest.mark.parametrize("w", [700.0, 64.0, 16.0, 1.0])
def test_truth_filter_matches_float64_reference(gl_ctx, w):
    c = _smooth_cube(32)
    got = filter_truth(c, w, ctx=gl_ctx)
    m = truth_grid_size(w, 32)
    assert got.shape == (6, m, m, 4)
    ref = convolve_exact(c, w, m)
    rel = np.abs(got - ref).max() / np.abs(ref).max()
    # GL path (w = 700) is float32 quadrature of the same sum; wide lobes use a box-reduced source
    # with >= 3 texels per lobe RMS angle (<= 1 % variance added); GL: footprint truncation, float32.
    assert rel < (1e-4 if w > 100 else 1e-2), rel


def test_truth_grid_sizes():
    assert truth_grid_size(math.inf, 64) == 64
    assert truth_grid_size(1022.0, 64) == 32      # the ladder's level 1 grid
    assert truth_grid_size(254.0, 64) == 16       # level 2
    assert truth_grid_size(1.0, 64) == 8          # never below 8 per face
    assert truth_grid_size(1e6, 16) == 8


def test_own_position_gives_zero_error(planes_scene, planes_probes, gl_ctx, tmp_path):
    """Every method, evaluated at a probe's own position, reproduces its capture: exactly in
    memory (float32), and to float16 rounding after a write/read round trip."""
    ps_mem = planes_probes
    w1 = float(ps_mem.manifest.lobes.powers[1])   # a ladder power: truth == bake level bit for bit
    p0 = ps_mem.manifest.streets[0].probes[0].position
    ps_disk = read_probe_set(write_probe_set(tmp_path / "ps", ps_mem, previews=False))
    for ps, tol in ((ps_mem, 1e-6), (ps_disk, 2e-3)):
        res = evaluate_scene(planes_scene, ps, positions=np.array([p0]), lobe_powers=(math.inf, w1), ctx=gl_ctx,
                             materials=(), keep_worst=0, floor_probes=0, resolution=32)
        assert {r["method"] for r in res.rows} == set(METHODS)
        for r in res.rows:
            # planes_mip_sigma stands in for one lobe with four sharper taps: not the lobe itself even at
            # the probe (measured 0.051 without the sun, 0.125 with it, at w1 = 254; exact at the mirror)
            bound = (0.07 if not r["sun"] else 0.15) if r["method"] == "planes_mip_sigma" and r["lobe_power"] else tol
            assert r["rel_rmse"] < bound, r


def test_planes_scene_parallax_converges_with_probe_resolution(planes_scene, gl_ctx):
    """In the planes scene three planes are the exact model: the ``planes`` error at the mirror
    level is resampling of the probe only, so it falls as the probe resolution grows, while
    ``nearest`` keeps its parallax error.  Positions: lateral offsets up to 7 m, heights
    0.8-2.5 m, along offsets up to 3 m; sun out of the sky (see docs/evaluation.md: a splatted
    sun at a wall edge turns one texel of bilinear alpha into a 1e7 error)."""
    pos = np.array([[3.0, 0.8, 4.0], [-2.0, 2.5, -5.0], [0.0, 1.0, 7.0]])
    errs = {}
    for n in (16, 32, 64):
        ps = bake_probe_set(planes_scene, resolution=n, spacing=20.0, ctx=gl_ctx, progress=False)
        res = evaluate_scene(planes_scene, ps, positions=pos, lobe_powers=(math.inf,), ctx=gl_ctx, materials=(),
                             keep_worst=0, floor_probes=0, resolution=64, sun_variants=(False,),
                             methods=("nearest", "planes"))
        errs[n] = (res.error("nearest", None, sun=False), res.error("planes", None, sun=False))
    # measured: planes 0.35, 0.27, 0.20; nearest 0.58-0.63
    assert errs[16][1] > errs[32][1] > errs[64][1]
    for n in errs:
        assert errs[n][1] < 0.65 * errs[n][0], errs
    assert errs[64][1] < 0.4 * errs[64][0], errs


def test_planes_mip_beats_nearest_on_planes(planes_scene, planes_probes, gl_ctx):
    pos = np.array([[3.0, 0.8, 4.0], [-2.0, 2.5, -5.0], [4.0, 1.5, 6.5]])
    res = evaluate_scene(planes_scene, planes_probes, positions=pos, lobe_powers=(math.inf, 256.0, 64.0), ctx=gl_ctx,
                         materials=(), keep_worst=0, floor_probes=0, sun_variants=(False,),
                         methods=("nearest", "planes", "planes_mip"))
    for lp in (None, 256.0, 64.0):
        assert res.error("planes_mip", lp, sun=False) < 0.75 * res.error("nearest", lp, sun=False), lp
    # the mip shift helps where lobes are filtered (not at the mirror level, where it is a no-op)
    assert res.error("planes_mip", 64.0, sun=False) < res.error("planes", 64.0, sun=False)


def test_depth_reproject_single_ground_plane():
    """Probe at the origin over a ground at y = -2 (sky above): the reprojected direction and
    the distance ratio of the analytic plane intersection, to the depth texel's resolution."""
    n = 128
    d = cube.texel_directions(n)
    with np.errstate(divide="ignore"):
        dist = np.where(d[..., 1] < -1e-3, -2.0 / d[..., 1], 0.0)
    dist = np.where(dist < 500, dist, 0.0)
    x = np.array([1.0, 0.5, 0.3])
    p = np.zeros(3)
    dirs = np.array([[0.0, -1.0, 0.0], [0.6, -0.8, 0.0], [-0.3, -0.5, 0.81], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    planes = np.array([-100.0, 100.0, -2.0])
    r, ratio = depth_reproject(x, dirs, p, dist, planes, along=0)
    r_ref, ratio_ref = parallax(x, dirs, p, planes, 0)  # exact: this scene is the ground plane
    assert np.all(np.isfinite(r)) and np.all(np.isfinite(ratio))
    np.testing.assert_allclose(r[:3], r_ref[:3], atol=2e-2)
    np.testing.assert_allclose(ratio[:3], ratio_ref[:3], rtol=2e-2)
    # up and horizontal: nothing behind along the ray: the sky, r = d and no shift
    np.testing.assert_allclose(r[3:], dirs[3:])
    np.testing.assert_allclose(ratio[3:], 1.0)


def test_predictor_matches_runtime_twin(planes_probes):
    """planes_mip and blend through the Predictor (local probe subset, street RGBA then sky) equal
    ``envcap.runtime.sampling.sample_street`` over the whole street."""
    pr = Predictor(planes_probes)
    street = RuntimeStreet.from_manifest(planes_probes.manifest.streets[0])
    chains = ProbeChains(planes_probes.levels, planes_probes.manifest.lobes.powers)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(0, 9, 500))
    for x in (np.array([2.5, 1.2, -4.0]), np.array([-7.0, 0.3, 8.5]), np.array([0.0, 2.0, 0.0])):
        for method in ("planes_mip", "blend"):
            got = pr.predict(method, "planes", x, d, w)
            ref = sample_street(chains, planes_probes.sky_levels, street, x, d, w, method)
            np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-9)


def test_sample_positions_bounds_and_determinism(planes_probes):
    m = planes_probes.manifest
    sw = Sweep(per_street=20, margin=1.5, seed=11)
    a = sample_positions(m, sw)
    b = sample_positions(m, sw)
    assert [p.position for p in a] == [p.position for p in b]
    st = m.streets[0]
    for p in a:
        x = np.array(p.position)
        assert st.planes.facade_min + 1.5 <= x[2] <= st.planes.facade_max - 1.5
        assert 0.3 <= x[1] <= 3.0
        assert st.start + 2.0 <= x[0] <= st.end - 2.0
        assert p.along <= 0.5 * m.probe_spacing + 1e-9
    # a street narrower than twice the margin is sampled on its probe line, not outside it
    narrow = sample_positions(m, Sweep(per_street=3, margin=50.0))
    assert all(p.lateral == 0.0 for p in narrow)


def test_bad_inputs(planes_scene, planes_probes, gl_ctx):
    kw = dict(ctx=gl_ctx, materials=(), keep_worst=0, floor_probes=0, lobe_powers=(math.inf,))
    with pytest.raises(ValueError, match="NaN or Inf"):
        evaluate_scene(planes_scene, planes_probes, positions=np.array([[0.0, np.nan, 0.0]]), **kw)
    with pytest.raises(ValueError, match="unknown"):
        evaluate_scene(planes_scene, planes_probes, positions=np.array([[0.0, 1.0, 0.0]]), methods=("magic",), **kw)
    with pytest.raises(ValueError, match="baked from scene"):
        evaluate_scene(load_scene("canyon"), planes_probes, positions=np.array([[0.0, 1.0, 0.0]]), **kw)
    with pytest.raises(ValueError, match="lobe powers"):
        evaluate_scene(planes_scene, planes_probes, positions=np.array([[0.0, 1.0, 0.0]]),
                       **{**kw, "lobe_powers": (-1.0,)})
    with pytest.raises(ValueError, match="per_street"):
        Sweep(per_street=0)
    with pytest.raises(ValueError, match="resolution"):
        evaluate_scene(planes_scene, planes_probes, positions=np.array([[0.0, 1.0, 0.0]]), resolution=2, **kw)
    with pytest.raises(ValueError, match="segment"):
        street_segment(planes_scene, -1.0)


def test_hard_positions_stay_finite(planes_scene, planes_probes, gl_ctx):
    """Positions on a facade plane, on the ground, outside the street and beyond the last probe:
    every method returns finite values (the runtime's fallbacks), no NaN."""
    pos = np.array([[1.0, 0.0, 0.0], [2.0, 1.0, 10.0], [3.0, 1.0, -10.0], [60.0, 1.0, 0.0], [0.0, 1.0, 15.0]])
    res = evaluate_scene(planes_scene, planes_probes, positions=pos, lobe_powers=(math.inf, 64.0), ctx=gl_ctx,
                         materials=(), keep_worst=0, floor_probes=0, sun_variants=(False,), resolution=16)
    assert len(res.rows) == 5 * 2 * len(METHODS)
    assert all(math.isfinite(r["rel_rmse"]) for r in res.rows)


def test_report_and_cli(planes_scene, planes_probes, gl_ctx, tmp_path, capsys):
    res = evaluate_scene(planes_scene, planes_probes, sweep=Sweep(per_street=2), lobe_powers=(math.inf, 64.0),
                         ctx=gl_ctx, keep_worst=1, floor_probes=1, resolution=16)
    out = write_report([res], tmp_path / "rep")
    doc = json.loads((out / "report.json").read_text())
    row = doc["results"][0]
    assert {"scene", "method", "lobe_power", "rel_rmse", "n_positions"} <= set(row)
    assert {r["method"] for r in doc["results"]} == set(METHODS)
    assert all(k in doc["timings"]["planes"] for k in ("captures_s", "filtering_s", "predictions_s", "total_s"))
    assert (out / "report.md").read_text().startswith("# envcap parallax evaluation")
    assert (out / "error_vs_lateral.png").stat().st_size > 0
    assert any(f.startswith("worst_planes_0") for f in doc["files"])
    # nothing to report: an error, and no directory left behind
    with pytest.raises(ValueError):
        write_report([], tmp_path / "none")
    assert not (tmp_path / "none").exists()
    # CLI: a missing probe set and a bad lobe list are one-line errors with status 2, no output
    rc = main(["evaluate", "planes", "--probes", str(tmp_path / "missing"), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("envcap: error:") and err.count("\n") == 1
    assert not (tmp_path / "o").exists()
    probes = write_probe_set(tmp_path / "ps", planes_probes, previews=False, exr=False)
    rc = main(["evaluate", "planes", "--probes", str(probes), "--out", str(tmp_path / "o2"), "--positions", "0"])
    assert rc == 2 and "positions" in capsys.readouterr().err
    assert not (tmp_path / "o2").exists()


@pytest.mark.parametrize("name", ["avenue", "imported"])
def test_planes_mip_beats_nearest_in_open_streets(gl_ctx, name):
    """A small version of the default sweep (20 m segment, 32^2, 4 positions, sun out of the sky)
    where parallax matters most: planes_mip below nearest at the mirror and at w = 256, 64, 16
    (measured ratios 2.2-4.2).  In the narrow canyon the same small setting gives 0.93 at w = 16
    (1.05 on the full default sweep; docs/evaluation.md): not asserted, reported."""
    sc = street_segment(load_scene(name), 20.0)
    ps = bake_probe_set(sc, resolution=32, spacing=10.0, ctx=gl_ctx, progress=False)
    res = evaluate_scene(sc, ps, sweep=Sweep(per_street=4), ctx=gl_ctx, materials=(), keep_worst=0, floor_probes=0,
                         lobe_powers=(math.inf, 256.0, 64.0, 16.0), sun_variants=(False,),
                         methods=("nearest", "planes_mip"), resolution=32)
    for lp in (None, 256.0, 64.0, 16.0):
        ratio = res.error("nearest", lp, sun=False) / res.error("planes_mip", lp, sun=False)
        assert ratio > (1.5 if lp is None or lp >= 64 else 1.2), (lp, ratio)
