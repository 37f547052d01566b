"""Bounds before work for an evaluation (issue 9, runaway memory and time): the position count,
the truth face size and the memory are checked before any capture, with one line naming the
option.  Old: ``--positions 100000000`` ran away (10^8 Python objects, then captures for days);
``--resolution 99999999999999999999`` failed with numpy's "Maximum allowed size exceeded";
``--resolution 6000`` tried to allocate the truth sky at 6000^2 (80 GiB by this model)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from envcap.core.budget import MEMORY_ENV, BudgetError
from envcap.evaluate.bounds import MAX_POSITIONS, estimate_evaluation
from envcap.evaluate.run import evaluate_scene
from envcap.evaluate.sweep import Sweep
from envcap.probeset.bake import bake_probe_set
from envcap.scene import load_scene
from envcap.scene.segment import street_segment

KW = {"materials": (), "keep_worst": 0, "floor_probes": 0, "lobe_powers": (math.inf,), "methods": ("nearest",)}


@pytest.fixture(scope="module")
def small(gl_ctx):
    scene = street_segment(load_scene("planes"), 20.0)
    return scene, bake_probe_set(scene, resolution=8, spacing=10.0, ctx=gl_ctx, progress=False)


def test_the_estimate_grows_with_positions_and_face_size():
    a = estimate_evaluation(16, 64)
    assert estimate_evaluation(32, 64).seconds > a.seconds and estimate_evaluation(16, 128).peak_bytes > a.peak_bytes
    # a face size past counting is infinite, never an OverflowError
    assert estimate_evaluation(1, 10 ** 400).peak_bytes == math.inf
    # the measured run (4 + 5 extra positions at 64^2, 7 powers x 6 methods: 32 s, 313 MB resident) is in range
    m = estimate_evaluation(4, 64)
    assert 10 < m.seconds < 100 and m.peak_bytes < 313e6


def test_too_many_positions_are_refused_before_any_capture(small, gl_ctx):
    scene, ps = small
    t0 = time.perf_counter()
    with pytest.raises(BudgetError, match=r"positions.*100,000,000 asked, more than the limit of 10,000; change --positions"):
        evaluate_scene(scene, ps, sweep=Sweep(per_street=100_000_000), ctx=gl_ctx, **KW)
    assert time.perf_counter() - t0 < 2.0
    # the limit counts every street's positions and can be raised (or lowered) by the caller
    with pytest.raises(BudgetError, match="limit of 1;"):
        evaluate_scene(scene, ps, sweep=Sweep(per_street=2), ctx=gl_ctx, max_positions=1, **KW)
    res = evaluate_scene(scene, ps, positions=np.array([[0.0, 1.5, 0.0]]), ctx=gl_ctx, resolution=4, max_positions=1, **KW)
    assert len(res.positions) == 1 and MAX_POSITIONS == 10_000


@pytest.mark.parametrize("resolution", [99999999999999999999, 9 ** 300, 6000])
def test_a_huge_truth_resolution_is_refused_naming_the_option(small, gl_ctx, resolution, monkeypatch):
    monkeypatch.setenv(MEMORY_ENV, "16G")
    scene, ps = small
    with pytest.raises(BudgetError, match=r"--resolution") as e:
        evaluate_scene(scene, ps, positions=np.array([[0.0, 1.5, 0.0]]), resolution=resolution, ctx=gl_ctx, **KW)
    msg = str(e.value)
    assert "\n" not in msg and "memory" in msg and len(msg) < 400, msg


def test_a_resolution_past_the_gl_target_is_refused_with_the_largest_that_fits(small, gl_ctx, monkeypatch):
    monkeypatch.setenv(MEMORY_ENV, "1000T")  # memory is no bound here: the GL limits are
    scene, ps = small
    most = min(gl_ctx.info["GL_MAX_TEXTURE_SIZE"], gl_ctx.info["GL_MAX_RENDERBUFFER_SIZE"]) // 3
    with pytest.raises(ValueError, match=rf"--resolution {most + 1}: .* use --resolution <= {most}"):
        evaluate_scene(scene, ps, positions=np.array([[0.0, 1.5, 0.0]]), resolution=most + 1, ctx=gl_ctx, **KW)


def test_a_negative_sweep_seed_is_named():
    """Old: numpy's "expected non-negative integer" from inside the sweep, naming nothing."""
    with pytest.raises(ValueError, match="seed must be an integer >= 0, got -1"):
        Sweep(seed=-1)
