"""Issue 9: bounds before work in the bake (count, memory, GL limits, float32 geometry).

Old behaviour: ``--resolution 100000`` built the sky first and died with a traceback ``Unable to
allocate 74.5 GiB`` (exit 1); ``--resolution 20000`` reached 6.7 GB in 15 s; ``--spacing 1e-9``
placed probes for 214 s up to 24 GB until the kernel killed it; a mesh ``scale = 1e30`` baked
and failed only when the EXR was written (``distance must be finite``).  New: one line, exit 2,
before the sky is built or anything is captured.
"""

from __future__ import annotations

import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

from envcap.cli import main
from envcap.core.budget import BudgetError
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.bake_bounds import (
    GEOMETRY_LIMIT_M,
    check_geometry,
    check_gl_limits,
    estimate_bake,
)
from envcap.probeset.placement import MAX_PROBES, place_probes, probe_count
from envcap.scene import load_scene
from envcap.scene.model import SceneMesh, Street

ROOT = Path(__file__).resolve().parents[2]
FAST_S = 5.0
"""Each refusal must come well before a capture at that size could even start (seconds)."""


@pytest.fixture(scope="module")
def canyon():
    return load_scene("canyon")


def refused(call, match: str) -> str:
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=match) as info:
        call()
    assert time.perf_counter() - t0 < FAST_S
    msg = str(info.value)
    assert "\n" not in msg
    return msg


def test_a_huge_resolution_is_refused_before_the_sky_is_built(canyon, monkeypatch):
    monkeypatch.delenv("ENVCAP_MAX_MEMORY", raising=False)
    n_probes = sum(len(place_probes(st, spacing=5.0)) for st in canyon.streets)
    msg = refused(lambda: bake_probe_set(canyon, resolution=100000, progress=False),
                  r"bake of 120 probes at 100000\^2 texels per face .*: needs [0-9.]+ TiB, more than the .* memory limit")
    assert n_probes == 120 and "change --resolution or --spacing" in msg
    # The arrays alone that such a bake holds: the float32 RGBA level 0 of 120 cubes (an
    # independent lower bound on the estimate).
    assert estimate_bake(120, 100000).peak_bytes > 120 * 6 * 100000**2 * 16


def test_a_resolution_that_fits_memory_but_not_the_gl_target_is_refused_with_the_largest_that_fits(
        canyon, gl_ctx, monkeypatch):
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "10000T")
    limit = min(gl_ctx.info["GL_MAX_TEXTURE_SIZE"], gl_ctx.info["GL_MAX_RENDERBUFFER_SIZE"])
    n = limit // 3 + 1
    refused(lambda: bake_probe_set(canyon, resolution=n, ctx=gl_ctx, progress=False),
            rf"--resolution {n}: the capture renders the 6 faces into one {3 * n} x {2 * n} target, past "
            rf"GL_MAX_\w+ {limit} of .*; use --resolution <= {limit // 3}")
    assert check_gl_limits(gl_ctx, limit // 3, 1) is None


def test_the_cube_map_array_layers_of_the_context_give_a_note(gl_ctx):
    layers = gl_ctx.info["GL_MAX_ARRAY_TEXTURE_LAYERS"]
    assert check_gl_limits(gl_ctx, 4, layers // 6) is None
    note = check_gl_limits(gl_ctx, 4, layers // 6 + 1)
    assert note is not None and f"GL_MAX_ARRAY_TEXTURE_LAYERS {layers}" in note


@pytest.mark.parametrize("spacing", [1e-9, 1e-300])
def test_a_tiny_spacing_is_refused_before_any_probe_is_placed(canyon, spacing):
    msg = refused(lambda: bake_probe_set(canyon, resolution=4, spacing=spacing, progress=False),
                  r"probes for 600 m of streets at spacing .* m \(~.*B, .* at llvmpipe rates\): .* asked, "
                  rf"more than the limit of {MAX_PROBES:,}; change --spacing")
    assert "max_probes=" in msg


def test_probe_count_is_what_place_probes_places_and_is_bounded():
    st = Street("s", "x", 0.0, 103.0, -5.0, 5.0)
    for spacing in (5.0, 7.3, 103.0, 500.0):
        assert probe_count(st, spacing) == len(place_probes(st, spacing=spacing))
    assert probe_count(Street("far", "x", -1e308, 1e308, -5.0, 5.0), 1e-300) == float("inf")
    with pytest.raises(BudgetError, match=r"probes on street 's' \(103 m at spacing 1 m\): 103 asked, more than the "
                                          r"limit of 100; change --spacing"):
        place_probes(st, spacing=1.0, max_probes=100)
    assert len(place_probes(st, spacing=1.0, max_probes=103)) == 103


def test_the_probe_limit_can_be_raised_by_the_caller(canyon, gl_ctx):
    with pytest.raises(BudgetError, match="limit of 5"):
        bake_probe_set(canyon, resolution=4, spacing=100.0, ctx=gl_ctx, progress=False, max_probes=5)
    ps = bake_probe_set(canyon, resolution=4, spacing=100.0, ctx=gl_ctx, progress=False, max_probes=6,
                        filter_levels=False)
    assert ps.layer_count == 6


def test_a_memory_limit_set_by_the_user_refuses_a_bake_that_would_fit_the_machine(canyon, gl_ctx, monkeypatch):
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "64M")
    refused(lambda: bake_probe_set(canyon, resolution=64, ctx=gl_ctx, progress=False),
            r"bake of 120 probes at 64\^2 .*: needs [0-9.]+ [MG]iB, more than the 64 MiB memory limit \(ENVCAP_MAX_MEMORY\)")


def test_the_estimate_covers_the_arrays_a_real_bake_returns(canyon_probe_set):
    """Independent lower bound: the bytes of the arrays the bake hands back (chain, distance, sky)."""
    ps = canyon_probe_set
    held = sum(a.nbytes for a in ps.levels) + ps.distance.nbytes + sum(a.nbytes for a in ps.sky_levels)
    est = estimate_bake(ps.layer_count, ps.resolution)
    assert est.peak_bytes > held
    assert est.texels == ps.layer_count * 6 * ps.resolution**2 == ps.levels[0][..., 0].size
    assert not est.big and estimate_bake(1000, 256).big


# Peak resident memory (MiB, ``/usr/bin/time -f %M``) of ``envcap capture SCENE --resolution N
# --spacing S --quality Q --quiet`` with llvmpipe on 2 cores (docs/reliability.md, Limits):
# (scene, probes, N, quality, measured).  Before the composed filter stopped copying, the model
# (fitted to the old filter) gave 868 MiB for canyon 30 x 128^2 composed, measured 377.
MEASURED_PEAKS_MIB = [
    ("canyon", 30, 16, "composed", 183), ("canyon", 30, 64, "composed", 227), ("canyon", 120, 64, "composed", 372),
    ("canyon", 30, 128, "composed", 377), ("canyon", 60, 128, "composed", 502), ("canyon", 120, 128, "composed", 651),
    ("canyon", 30, 256, "composed", 670), ("canyon", 60, 256, "composed", 967), ("avenue", 50, 64, "composed", 229),
    ("avenue", 25, 128, "composed", 313), ("avenue", 50, 128, "composed", 446),
    ("canyon", 30, 64, "default", 374), ("canyon", 120, 64, "default", 896), ("canyon", 30, 128, "default", 910),
    ("canyon", 60, 128, "default", 1287), ("canyon", 30, 256, "default", 1687), ("avenue", 50, 128, "default", 1206),
]
# The same with ``--ladder half_octave`` (4 rung layers per level): (probes, N, measured MiB).
MEASURED_RUNG_PEAKS_MIB = [(60, 64, 578), (30, 128, 991)]


@pytest.mark.parametrize("quality", ["composed", "default"])
def test_the_estimate_bounds_the_measured_peaks_closely(quality):
    """An upper bound on every measured peak (the process's baseline included), and close to it: an
    overestimate refuses bakes that would fit (composed 1.04-1.23x, default 1.08-1.25x)."""
    cases = [c for c in MEASURED_PEAKS_MIB if c[3] == quality]
    for scene, probes, n, _, mib in cases:
        est = estimate_bake(probes, n, quality=quality).peak_bytes / 2**20
        assert mib <= est <= 1.3 * mib, (scene, probes, n, quality, mib, est)
    if quality == "composed":
        for probes, n, mib in MEASURED_RUNG_PEAKS_MIB:
            est = estimate_bake(probes, n, quality=quality, rungs_per_level=4).peak_bytes / 2**20
            assert mib <= est <= 1.3 * mib, (probes, n, mib, est)


def test_the_composed_estimate_covers_its_own_arrays_and_grows_with_the_batch():
    """Independent lower bound for the composed filter: the process's baseline (a 16^2 bake, 183
    MiB) plus the float32 chain (16 B x 4/3) and distance (4 B) per level-0 texel; and within one
    prefilter batch the cost per texel is above what is kept, past it exactly what is kept."""
    for probes, n in ((1, 4), (30, 128), (500, 256)):
        texels = probes * 6 * n * n
        assert estimate_bake(probes, n, quality="composed").peak_bytes > 183 * 2**20 + texels * (16 * 4 / 3 + 4)
    small = [estimate_bake(p, 128, quality="composed").peak_bytes for p in (10, 20, 200, 400)]
    kept = (small[3] - small[2]) / (200 * 6 * 128 * 128)
    assert 21 + 16 / 3 <= kept < (small[1] - small[0]) / (10 * 6 * 128 * 128)
    assert estimate_bake(120, 128, quality="composed").peak_bytes < 0.5 * estimate_bake(120, 128).peak_bytes


def test_geometry_past_float32_distance_range_is_refused_before_capture(canyon):
    """The limit is where float32 squared distances overflow: checked here with float32 arithmetic."""
    def mesh(extent: float) -> SceneMesh:
        p = np.array([[extent, extent, extent], [-extent, -extent, -extent], [0, 0, 0]], np.float32)
        z = np.zeros((3, 3), np.float32)
        return SceneMesh(p, z + [0, 1, 0], z, z, np.array([[0, 1, 2]], np.uint32))

    def squared_distance_f32(extent: float) -> np.float32:
        with np.errstate(over="ignore"):
            d = np.float32(extent) - np.float32(-extent)
            return np.float32(3) * d * d

    inside, outside = 0.99 * GEOMETRY_LIMIT_M, 1.02 * GEOMETRY_LIMIT_M
    assert np.isfinite(squared_distance_f32(inside)) and not np.isfinite(squared_distance_f32(outside))
    canyon_inside = type(canyon)(canyon.name, mesh(inside), canyon.streets, canyon.sky, canyon.effects)
    check_geometry(canyon_inside, np.zeros((1, 3)))
    far = type(canyon)(canyon.name, mesh(outside), canyon.streets, canyon.sky, canyon.effects,
                       meta={"source": "/x/scene.toml"})
    with pytest.raises(ValueError, match=r"scene 'canyon' \(/x/scene\.toml\): mesh coordinates reach 5\.43e\+18 m, "
                                         r"past the 5\.3e\+18 m .*; check the mesh's scale and offset"):
        check_geometry(far, np.zeros((1, 3)))
    with pytest.raises(ValueError, match="probe positions reach 5.43e"):
        check_geometry(canyon_inside, np.array([[0.0, 2.0, outside]]))
    # The bake checks before the sky or any capture: a sky that would take minutes is never built.
    refused(lambda: bake_probe_set(far, resolution=4, spacing=100.0, progress=False), "mesh coordinates reach")


def test_a_mesh_scale_of_1e30_fails_at_once_naming_the_mesh(tmp_path, capsys):
    """``[mesh] scale = 1e30``: before, the whole bake ran and the EXR write failed.  Now the
    scene loader refuses the scale itself, and the bake's geometry check stands behind it for
    meshes built in Python (above)."""
    src = ROOT / "city_scenes/imported.toml"
    text = src.read_text()
    assert tomllib.loads(text)["mesh"]["scale"] == 1.0
    scene = tmp_path / "imported.toml"
    scene.write_text(text.replace("scale = 1.0", "scale = 1e30").replace(
        'file = "imported_block/"', f'file = "{(src.parent / "imported_block").as_posix()}/"'))
    t0 = time.perf_counter()
    code = main(["capture", str(scene), "--out", str(tmp_path / "out"), "--resolution", "4", "--spacing", "1000"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and time.perf_counter() - t0 < 20
    assert err == [err[-1]] and err[-1].startswith("envcap: error: ") and "mesh" in err[-1]  # one line, no bake
    assert not (tmp_path / "out").exists()


def test_the_cli_refuses_a_huge_resolution_in_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("ENVCAP_MAX_MEMORY", raising=False)
    t0 = time.perf_counter()
    code = main(["capture", "canyon", "--out", str(tmp_path / "out"), "--resolution", "20000"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and time.perf_counter() - t0 < 10
    assert len(err) == 1 and err[0].startswith("envcap: error: bake of 120 probes at 20000^2 texels per face")
    assert not (tmp_path / "out").exists()
