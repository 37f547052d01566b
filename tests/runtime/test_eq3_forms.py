"""Eq. 3 in both forms (docs/runtime.md, "Two forms of Eq. 3"): GLSL ``envcap_shade_lafortune``
(default, and with ``#define ENVCAP_EQ3_PAPER_FORM``) against the numpy twin
``shade_lafortune(form=...)`` through the full lookup of the synthetic street; the forms against
closed forms under a constant environment."""

import numpy as np
import pytest

from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.shading import lafortune_lobe, shade_lafortune

from runtime_fixtures import ARGS, DECL

# Two lobes (anisotropic w = 60, mirror-like w = 300), as the "aniso" material of test_lafortune
RHO_D = np.array([0.05, 0.04, 0.03])
C = np.array([[-1.2, -0.6, 0.9], [-1.0, -1.0, 1.0]])
W = np.array([60.0, 300.0])
RHO_S = np.array([[0.4 * 62 / (2 * np.pi)] * 3, [0.1 * 302 / (2 * np.pi)] * 3])

BODY = f"""
vec4 C[ENVCAP_MAX_LOBES]; vec3 rs[ENVCAP_MAX_LOBES];
for (int k = 0; k < ENVCAP_MAX_LOBES; ++k) {{ C[k] = vec4(0.0); rs[k] = vec3(0.0); }}
C[0] = vec4({C[0, 0]}, {C[0, 1]}, {C[0, 2]}, {W[0]}); rs[0] = vec3({RHO_S[0, 0]});
C[1] = vec4({C[1, 0]}, {C[1, 1]}, {C[1, 2]}, {W[1]}); rs[1] = vec3({RHO_S[1, 0]});
o[i] = vec4(envcap_shade_lafortune(probes, sky, x[i].xyz, t[i].xyz, b[i].xyz, nrm[i].xyz, v[i].xyz,
                                   vec3({RHO_D[0]}, {RHO_D[1]}, {RHO_D[2]}), C, rs, 2, {ARGS}), 0.0);
"""


def f32(a):
    return np.asarray(a, np.float32).astype(np.float64)


def random_shading(n, seed):
    """Points in the street, orthonormal frames (rows T, B, N) and local views above the surface."""
    rng = np.random.default_rng(seed)
    x = np.c_[rng.uniform(-2, 22, n), rng.uniform(0.2, 10, n), rng.uniform(-5, 5, n)]
    N = rng.normal(size=(n, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    T = np.cross(N, rng.normal(size=(n, 3)))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    F = np.stack([T, np.cross(N, T), N], 1)
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2]) + 0.05
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return x, F, v


@pytest.mark.parametrize("form", ["envcap", "paper"])
def test_shade_glsl_matches_twin_in_both_forms(gl_ctx, scene, form):
    probes, sky, street, powers, pt, st = scene
    n = 20_000
    x, F, v_local = random_shading(n, seed=21)
    F, v_local, x = f32(F), f32(v_local), f32(x)
    v_world = np.einsum("ni,nij->nj", v_local, F)
    uni = street.uniforms(powers)
    got = run_glsl(gl_ctx, BODY, {"x": uni.to_local(x), "t": F[:, 0], "b": F[:, 1], "nrm": F[:, 2], "v": v_world},
                   {"o": 3}, uniforms=uni.values(), declarations=DECL, probes=pt, sky=st,
                   defines={"ENVCAP_EQ3_PAPER_FORM": 1} if form == "paper" else None)["o"]
    chains = ProbeChains(probes, powers)
    env = lambda d, w: sample_street(chains, sky, street, x, d, w, "planes_mip")  # noqa: E731
    ref = shade_lafortune(env, v_local, F, RHO_D, C, W, RHO_S, form=form)
    assert np.all(np.isfinite(got))
    # float32 lobe weights (<= 1e-4 relative at w = 300, docs/runtime.md) and lookups (4e-6 x max)
    np.testing.assert_allclose(got, ref, rtol=2e-4, atol=4e-6 * np.abs(ref).max())
    if form == "paper":   # the switch took effect: lobes off the normal are brighter without the cosine
        other = shade_lafortune(env, v_local, F, RHO_D, C, W, RHO_S, form="envcap")
        assert np.mean(np.abs(got - other).sum(1) > 1e-3 * np.abs(other).sum(1)) > 0.9


def test_forms_under_a_constant_environment():
    """E_w = L0 for every w: Eq. 3 reduces to rho_d L0 + sum rho_s |Cv|^w 2 pi / (1 + w) (paper)
    and the same with each lobe times max(c_z, 0) (envcap), computed here with ``**``."""
    x, F, v = random_shading(500, seed=5)
    L0 = np.array([1.5, 1.0, 0.5])
    env = lambda d, w: np.broadcast_to(L0, d.shape)  # noqa: E731
    paper = shade_lafortune(env, v, F, RHO_D, C, W, RHO_S, form="paper")
    envcap = shade_lafortune(env, v, F, RHO_D, C, W, RHO_S, form="envcap")
    want_p = np.broadcast_to(RHO_D * L0, v.shape).copy()
    want_e = want_p.copy()
    for Ci, wi, rs in zip(C, W, RHO_S):
        cv = Ci * v
        ln = np.linalg.norm(cv, axis=1)
        mag = ln ** wi * 2 * np.pi / (1 + wi)
        want_p += (mag[:, None] * rs) * L0
        want_e += ((mag * np.maximum(cv[:, 2] / ln, 0))[:, None] * rs) * L0
    np.testing.assert_allclose(paper, want_p, rtol=1e-12)
    np.testing.assert_allclose(envcap, want_e, rtol=1e-12)


def test_unknown_form_is_rejected():
    with pytest.raises(ValueError, match="form"):
        lafortune_lobe([0, 0, 1], [1, 1, 1], 5.0, form="Paper")  # type: ignore[arg-type]
