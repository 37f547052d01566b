"""envcap.gpu.glsl_harness: inputs and outputs round-trip, split dispatches, clear errors."""

import numpy as np
import pytest

from envcap.gpu import glsl_harness
from envcap.gpu.glsl_harness import build_source, run_glsl


def test_roundtrip_and_arithmetic(gl_ctx):
    rng = np.random.default_rng(0)
    a = rng.normal(size=(1000, 3)).astype(np.float32)
    b = rng.normal(size=1000).astype(np.float32)
    out = run_glsl(gl_ctx, "o[i] = vec4(a[i].xyz * b[i].x, float(i)); q[i] = a[i];", {"a": a, "b": b},
                   {"o": 4, "q": 3}, includes=())
    np.testing.assert_array_equal(out["o"][:, :3], a * b[:, None])       # IEEE float32 multiply
    np.testing.assert_array_equal(out["o"][:, 3], np.arange(1000, dtype=np.float32))
    np.testing.assert_array_equal(out["q"], a)


def test_split_dispatch_covers_every_index(gl_ctx, monkeypatch):
    monkeypatch.setattr(glsl_harness, "MAX_GROUPS", 3)   # 192 invocations per dispatch
    n = 1000
    out = run_glsl(gl_ctx, "o[i] = vec4(float(i) + a[i].x);", {"a": np.ones(n)}, {"o": 1}, includes=())
    np.testing.assert_array_equal(out["o"][:, 0], np.arange(n) + 1.0)


def test_uniform_arrays_and_ints(gl_ctx):
    out = run_glsl(gl_ctx, "o[i] = vec4(tab[int(a[i].x)] * float(k));", {"a": np.array([0, 3, 15])}, {"o": 1},
                   includes=(), declarations="uniform float tab[16]; uniform int k;",
                   uniforms={"tab": np.arange(16) * 0.5, "k": 3})
    np.testing.assert_array_equal(out["o"][:, 0], [0.0, 4.5, 22.5])


def test_errors():
    with pytest.raises(ValueError, match="same length"):
        run_glsl(None, "", {"a": np.zeros(3), "b": np.zeros(4)}, {"o": 1})
    with pytest.raises(ValueError, match="k <= 4"):
        run_glsl(None, "", {"a": np.zeros((3, 5))}, {"o": 1})
    with pytest.raises(ValueError, match="1..4"):
        run_glsl(None, "", {"a": np.zeros(3)}, {"o": 5})
    with pytest.raises(FileNotFoundError):
        build_source("", ["a"], ["o"], includes=("no_such_shader.glsl",))


def test_bad_glsl_raises(gl_ctx):
    with pytest.raises(Exception, match="(?i)error"):
        run_glsl(gl_ctx, "o[i] = undefined_function(a[i]);", {"a": np.zeros(4)}, {"o": 4}, includes=())
