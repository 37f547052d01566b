"""The registry of parallax methods (envcap.runtime.methods): a method registered from outside the
package (here ``nearest_no_sky``, defined in this file: one function + one ParallaxMethod line) is
found by the runtime twin and by the evaluator by name; the built-in methods declare what they
need and document their parameters."""

import importlib
import math

import numpy as np
import pytest

from envcap.core import cube_sampling
from envcap.core.lobes import z_of_w as z_ref
from envcap.evaluate.run import evaluate_scene
from envcap.probeset.bake import bake_probe_set
from envcap.runtime import methods
from envcap.runtime.chains import ProbeChains
from envcap.runtime.methods import BUILTIN, METHODS, ParallaxMethod
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet
from envcap.scene import load_scene
from envcap.scene.segment import street_segment

from runtime_fixtures import probe_set


def nearest_no_sky(chains: ProbeChains, street: RuntimeStreet, x, d, w):
    """The nearest probe along ``d`` made opaque: the sky never shows through."""
    rgba = chains.fetch(d, street.layers[street.nearest(x)], w)
    return np.concatenate([rgba[..., :3], np.ones_like(rgba[..., 3:])], axis=-1)


NEAREST_NO_SKY = ParallaxMethod("nearest_no_sky", nearest_no_sky, "nearest probe, no parallax, sky dropped")


@pytest.fixture
def registered():
    methods.register(NEAREST_NO_SKY)
    yield NEAREST_NO_SKY
    methods.unregister(NEAREST_NO_SKY.name)


def test_registered_method_runs_in_the_runtime_twin(registered):
    probes, sky, street, powers = probe_set()
    rng = np.random.default_rng(2)
    n = 3000
    x = np.c_[rng.uniform(-5, 25, n), rng.uniform(0.5, 4, n), rng.uniform(-5, 5, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(0.0, np.log(powers[0]), n))
    got = sample_street(ProbeChains(probes, powers), sky, street, x, d, w, "nearest_no_sky")
    # reference: nearest probe by hand, level by envcap.core.lobes.z_of_w, no sky term at all
    layer = np.argmin(np.abs(x[:, :1] - street.positions[:, 0]), axis=1)
    ref = cube_sampling.sample_cube_array(probes, d, street.layers[layer], z_ref(w, powers))[..., :3]
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12)
    # where the street does not cover the lobe, the built-in nearest adds the sky: they differ there
    plain = sample_street(ProbeChains(probes, powers), sky, street, x, d, w, "nearest")
    open_sky = cube_sampling.sample_cube_array(probes, d, street.layers[layer], z_ref(w, powers))[..., 3] < 0.5
    assert open_sky.sum() > 100 and np.all(plain[open_sky].sum(axis=1) > got[open_sky].sum(axis=1))


def test_registered_method_runs_in_the_evaluator(registered, gl_ctx):
    """At a probe's own position ``nearest`` reproduces the capture; ``nearest_no_sky`` misses the
    open sky of the planes scene."""
    scene = street_segment(load_scene("planes"), 20.0)
    ps = bake_probe_set(scene, resolution=16, spacing=10.0, ctx=gl_ctx, progress=False)
    p0 = ps.manifest.streets[0].probes[0].position
    res = evaluate_scene(scene, ps, positions=np.array([p0]), methods=("nearest", "nearest_no_sky"),
                         lobe_powers=(math.inf,), ctx=gl_ctx, materials=(), keep_worst=0, floor_probes=0,
                         sun_variants=(False,), resolution=16)
    assert res.meta["methods"] == ["nearest", "nearest_no_sky"]
    assert res.error("nearest", None, sun=False) < 1e-6
    assert res.error("nearest_no_sky", None, sun=False) > 0.05


def test_registry_rules():
    assert methods.registered()[: len(METHODS)] == METHODS
    with pytest.raises(ValueError, match="already registered"):
        methods.register(BUILTIN[0])
    with pytest.raises(ValueError, match="unknown parallax method 'magic'.*planes_mip"):
        methods.get("magic")
    with pytest.raises(ValueError, match="planes"):
        ParallaxMethod("x", nearest_no_sky, "bad plane set", planes="measured")
    assert "nearest_no_sky" not in methods.registered()


@pytest.mark.parametrize("method", BUILTIN, ids=lambda m: m.name)
def test_builtin_methods_document_needs_and_parameters(method):
    """One file per method; its docstring states what it needs and every parameter."""
    doc = importlib.import_module(f"envcap.runtime.methods.{method.name}").__doc__
    assert doc.startswith(f"``{method.name}``") and "Needs" in doc and "Parameters" in doc
    assert all(f"``{k}``" in doc for k in method.parameters)
    assert (method.glsl is None) or (method.glsl in doc)
