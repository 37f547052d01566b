"""Many spheres (envcap.dynamic.spheres, .terms, .quadrature.union_lobe_fraction): the buffer's
checks, the K most occluding spheres against brute force, the union reference against closed
forms and Monte Carlo, the overlap rules, and GLSL (shaders/runtime/envcap_dynamic_spheres.glsl,
spheres in a uniform array) against the numpy twin."""

import math

import numpy as np
import pytest

from envcap.dynamic import cap_lobe_integral, cap_solid_angle
from envcap.dynamic.cap_lobe import cap_half_angle, occlusion
from envcap.dynamic.quadrature import union_lobe_fraction
from envcap.dynamic.spheres import COMBINE_RULES, SphereBuffer, cap_overlap, combine, select_spheres
from envcap.runtime.lafortune import quadrature
from envcap.dynamic.terms import dynamic_terms, mirror, shade_with_spheres
from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime.lafortune import Lafortune
from envcap.runtime.shading import shade_lafortune

INCLUDES = ("runtime/envcap_dynamic_spheres.glsl",)
ENV_GLSL = """vec3 sky_env(vec3 d, float w) {
    return vec3(1.0 + 0.5 * d.y, 0.7 + 0.2 * d.x - 0.1 * d.z, 0.3 + 0.05 * log(1.0 + w) / log(1.0e30)); }
"""


def sky_env(d, w):
    return np.stack([1 + 0.5 * d[..., 1], 0.7 + 0.2 * d[..., 0] - 0.1 * d[..., 2],
                     0.3 + 0.05 * np.log1p(w) / np.log(1e30)], axis=-1)


def random_spheres(rng, n):
    centers = rng.uniform(-4, 4, (n, 3)) * (1, 0.3, 1) + (0, 1, 0)
    return SphereBuffer(centers, rng.uniform(0.2, 0.8, n), rng.uniform(0, 1, (n, 3)))


def test_buffer_checks_and_array_round_trip():
    arr = np.array([[0, 1, 2, 0.5, 0.1, 0.2, 0.3], [1, 1, 1, 0.0, 1, 1, 1]])
    sb = SphereBuffer.from_array(arr)
    np.testing.assert_array_equal(sb.as_array(), arr)
    assert len(sb) == 2
    for bad, msg in [(dict(radii=[-1.0]), "radii"), (dict(albedo=[[2.0, 0, 0]]), "albedo"),
                     (dict(centers=[[np.nan, 0, 0]]), "finite"), (dict(radii=[1.0, 2.0]), "must match")]:
        kw = dict(centers=[[0.0, 0, 0]], radii=[1.0], albedo=[[0.5, 0.5, 0.5]]) | bad
        with pytest.raises(ValueError, match=msg):
            SphereBuffer(**kw)
    with pytest.raises(ValueError, match=r"\(N, 7\)"):
        SphereBuffer.from_array(np.zeros((2, 6)))
    with pytest.raises(ValueError, match="cap"):
        select_spheres(np.zeros(3), sb, cap=0)


def test_selection_is_the_largest_solid_angles():
    rng = np.random.default_rng(5)
    sb = random_spheres(rng, 30)
    x = rng.uniform(-4, 4, (200, 3)) * (1, 0.3, 1) + (0, 1, 0)
    sel = select_spheres(x, sb, cap=5)
    ell = np.linalg.norm(sb.centers[None] - x[:, None], axis=2)
    omega = cap_solid_angle(sb.radii[None] / ell)               # 4 pi inside a sphere
    want = np.argsort(-omega, axis=1, kind="stable")[:, :5]
    np.testing.assert_array_equal(np.sort(sel.index, axis=1), np.sort(want, axis=1))
    # fewer spheres than the cap, and an empty slot (radius 0): index -1, blocks nothing
    few = SphereBuffer([[0, 0, 3.0], [0, 0, -3.0]], [1.0, 0.0], [[1, 1, 1]] * 2)
    s2 = select_spheres(np.zeros((1, 3)), few, cap=3)
    np.testing.assert_array_equal(s2.index, [[0, -1, -1]])


def test_union_reference_against_closed_forms_and_monte_carlo():
    for th, g, w in [(0.3, 0.5, 10.0), (1.2, 2.0, 0.5), (0.2, 0.0, 3.0)]:
        D = np.array([[math.sin(g), 0, math.cos(g)]])
        truth = cap_lobe_integral(th, g, w) * (1 + w) / (2 * math.pi)
        assert abs(union_lobe_fraction(D, [th], np.array([0, 0, 1.0]), w) - truth) < 1e-5
    rng = np.random.default_rng(0)
    D = rng.normal(size=(6, 3))
    D /= np.linalg.norm(D, axis=1, keepdims=True)
    th = rng.uniform(0.2, 0.7, 6)
    u = rng.normal(size=(1_000_000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    lobe = np.maximum(u[:, 2], 0) ** 3
    hit = lobe * np.any(u @ D.T >= np.cos(th), axis=1)
    mc, sd = hit.sum() / lobe.sum(), hit.std() / lobe.mean() / math.sqrt(len(u))
    assert abs(union_lobe_fraction(D, th, np.array([0, 0, 1.0]), 3.0) - mc) < 4 * sd + 2e-4


def test_combine_rules_exact_cases():
    U, share = combine([[0.2, 0.3, 0.0]], "sum")               # disjoint caps: the sum is exact
    assert U[0] == pytest.approx(0.5) and share.sum() == pytest.approx(0.5)
    U, _ = combine([[0.4, 0.4]], "max")                         # identical caps: the max is exact
    assert U[0] == pytest.approx(0.4)
    U, share = combine([[0.5, 0.5]], "independent")
    assert U[0] == pytest.approx(0.75) and share[0] == pytest.approx([0.375, 0.375])
    # overlap: disjoint -> the sum, nested -> the max, half -> sum - half the smaller
    for o, want in [(0.0, 0.5), (1.0, 0.3), (0.5, 0.4)]:
        U, _ = combine([[0.3, 0.2]], "overlap", [[[0, o], [o, 0]]])
        assert U[0] == pytest.approx(want)
    with pytest.raises(ValueError, match="needs the pairs"):
        combine([[0.1]], "overlap")
    U, share = combine([[0.0, 0.0]], "independent")
    assert U[0] == 0 and np.all(share == 0)
    with pytest.raises(ValueError, match="combine rule"):
        combine([[0.1]], "union")


def test_cap_overlap_against_a_direction_grid():
    dirs, dw = quadrature(128)
    for t1, t2, b in [(0.3, 0.2, 0.35), (0.5, 0.5, 0.2), (1.0, 0.4, 1.2), (1.4, 1.2, 2.0)]:
        D2 = np.array([math.sin(b), 0, math.cos(b)])
        lens = ((dirs[:, 2] >= math.cos(t1)) & (dirs @ D2 >= math.cos(t2))) @ dw
        assert cap_overlap(t1, t2, b) == pytest.approx(lens / (2 * np.pi * (1 - math.cos(min(t1, t2)))), abs=3e-3)
    assert cap_overlap(0.2, 0.3, 0.6) == 0 and cap_overlap(0.1, 0.5, 0.3) == 1


def test_two_identical_and_two_disjoint_spheres_against_the_union_reference():
    """The union reference tells the rules apart: coincident spheres (max exact) and far-apart
    ones (sum exact); the overlap and rings rules are exact in both, the independent one (2f - f^2)
    in neither."""
    C = np.array([0.0, 0.0, 1.0])
    th = 0.3
    for D, best in [(np.array([[0.3, 0, 1], [0.3, 0, 1]]), "max"), (np.array([[0.5, 0, 1], [-0.5, 0, 1]]), "sum")]:
        D = D / np.linalg.norm(D, axis=1, keepdims=True)
        truth = union_lobe_fraction(D, [th, th], C, 10.0)
        t = math.cos(th) / (1 - math.cos(th))
        f = occlusion(D, C, t, 10.0).integral * 11 / (2 * math.pi)
        beta = math.acos(np.clip(D[0] @ D[1], -1, 1))
        o = float(cap_overlap(th, th, beta))
        lobe = (D[None], np.full((1, 2), t), C, 10.0)
        errs = {r: abs(float(combine(f[None], r, [[[0, o], [o, 0]]], lobe=lobe)[0][0]) - truth) for r in COMBINE_RULES}
        assert errs[best] < 2e-3 and errs["overlap"] < 2e-3 and errs["rings"] < 2e-3
        assert errs[best] < errs["independent"] / 4


def test_spheres_below_the_horizon_do_not_take_the_slots(gl_ctx):
    """Eight big spheres behind a surface (normal +Z) and one small one in front, cap 4: the one in
    front must be kept (ranking by solid angle alone dropped it, and the terms came out 0)."""
    behind = [[np.cos(a) * 1.5, np.sin(a) * 1.5, -2.0] for a in np.linspace(0, 2 * np.pi, 8, endpoint=False)]
    sb = SphereBuffer(behind + [[0.0, 0.0, 3.0]], [1.2] * 8 + [0.8], [[0.5, 0.5, 0.5]] * 9)
    sel = select_spheres(np.zeros((1, 3)), sb, cap=4, normal=np.array([[0.0, 0.0, 1.0]]))
    np.testing.assert_array_equal(sel.index, [[8, -1, -1, -1]])
    assert list(select_spheres(np.zeros((1, 3)), sb, cap=4).index[0]).count(8) == 0     # without the normal: dropped
    body = """EnvcapSphereSet s = envcap_select_spheres(x[i].xyz, vec3(0.0, 0.0, 1.0));
idx[i] = vec4(s.index[0], s.index[1], s.index[2], s.index[3]);"""
    got = run_glsl(gl_ctx, body, {"x": np.zeros((1, 3))}, {"idx": 4}, includes=INCLUDES,
                   defines={"ENVCAP_SPHERE_CAP": 4},
                   uniforms={"envcap_spheres": np.c_[sb.centers, sb.radii], "envcap_sphere_albedo": sb.albedo,
                             "envcap_sphere_count": len(sb)})
    np.testing.assert_array_equal(got["idx"], [[8, -1, -1, -1]])


def gl_selection(ctx, x, sb, C, w, defines):
    body = """EnvcapSphereSet s = envcap_select_spheres(x[i].xyz, vec3(0.0));
vec4 occ[ENVCAP_SPHERE_CAP];
float U = envcap_sphere_shares(s, normalize(c[i].xyz), c[i].w, occ);
idx[i] = vec4(s.index[0], s.index[1], s.index[2], s.index[3]);
sh[i] = vec4(occ[0].w, occ[1].w, occ[2].w, occ[3].w);
u[i] = vec4(U, s.lobe[0].w, occ[0].xy);"""
    return run_glsl(ctx, body, {"x": x, "c": np.c_[C, w]}, {"idx": 4, "sh": 4, "u": 4}, includes=INCLUDES,
                    defines={"ENVCAP_SPHERE_CAP": 4, **defines},
                    uniforms={"envcap_spheres": np.c_[sb.centers, sb.radii], "envcap_sphere_albedo": sb.albedo,
                              "envcap_sphere_count": len(sb)})


@pytest.mark.parametrize("form,rule,defines", [("envcap", "rings", {}), ("envcap", "overlap", {"ENVCAP_DYNAMIC_COMBINE": 0}),
                                               ("paper", "independent", {"ENVCAP_DYNAMIC_PAPER_FORM": 1, "ENVCAP_DYNAMIC_COMBINE": 1})])
def test_glsl_selection_and_shares_match_the_twin(gl_ctx, form, rule, defines):
    rng = np.random.default_rng(11)
    sb = random_spheres(rng, 40)
    n = 10_000
    x = rng.uniform(-4, 4, (n, 3)) * (1, 0.3, 1) + (0, 1, 0)
    C = rng.normal(size=(n, 3))
    C /= np.linalg.norm(C, axis=1, keepdims=True)
    w = np.exp(rng.uniform(0, np.log(300), n))
    got = gl_selection(gl_ctx, x, sb, C, w, defines)
    sel = select_spheres(x, sb, cap=4)
    # a near-tie at the 4th / 5th sphere may order differently in float32: leave those out
    t5 = np.sort(select_spheres(x, sb, cap=5).t, axis=1)
    clear = np.abs(t5[:, 3] - t5[:, 4]) > 1e-4 * t5[:, 3]
    np.testing.assert_array_equal(got["idx"][clear].astype(int), sel.index[clear])
    occ = occlusion(sel.D, C[:, None], sel.t, w[:, None], form=form)
    f = np.where(sel.index >= 0, occ.integral * (1 + w[:, None]) / (2 * np.pi), 0)
    U, share = combine(f, rule, sel.overlap, lobe=(sel.D, sel.t, C, w))
    # measured 1.7e-5 (w up to 300: slopes up to ~sqrt(w) times llvmpipe's 3.5e-6 rad atan)
    assert np.abs(got["u"][clear, 0] - U[clear]).max() < 1e-4
    assert np.abs(got["sh"][clear] - share[clear]).max() < 1e-4
    np.testing.assert_allclose(got["u"][clear, 1], sel.t[clear, 0], rtol=1e-4, atol=1e-4)   # t ~ 0: touching


def test_glsl_terms_match_the_twin_and_vanish_without_spheres(gl_ctx):
    rng = np.random.default_rng(12)
    sb = random_spheres(rng, 12)
    n = 1000
    x = rng.uniform(-4, 4, (n, 3)) * (1, 0.3, 1) + (0, 1, 0)
    N = rng.normal(size=(n, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    T = np.cross(N, rng.normal(size=(n, 3)))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    B = np.cross(N, T)
    vl = rng.normal(size=(n, 3)) * (1, 1, 0.3)
    vl[:, 2] = np.abs(vl[:, 2]) + 0.2
    vl /= np.linalg.norm(vl, axis=1, keepdims=True)
    v = vl[:, :1] * T + vl[:, 1:2] * B + vl[:, 2:] * N
    mat = Lafortune((0.4, 0.5, 0.6), ((-1.0, -1.0, 1.0), (-0.5, -0.5, 0.9)), (20.0, 300.0),
                    ((0.2, 0.2, 0.2), (0.1, 0.15, 0.1)))
    body = """vec4 C[ENVCAP_MAX_LOBES] = vec4[](vec4(-1.0, -1.0, 1.0, 20.0), vec4(-0.5, -0.5, 0.9, 300.0), vec4(0.0));
vec3 rs[ENVCAP_MAX_LOBES] = vec3[](vec3(0.2), vec3(0.1, 0.15, 0.1), vec3(0.0));
vec3 bl, bo;
envcap_dynamic_terms(x[i].xyz, t[i].xyz, b[i].xyz, nn[i].xyz, v[i].xyz, vec3(0.4, 0.5, 0.6), C, rs, 2, bl, bo);
o1[i] = vec4(bl, 0.0); o2[i] = vec4(bo, 0.0);"""
    uni = {"envcap_spheres": np.c_[sb.centers, sb.radii], "envcap_sphere_albedo": sb.albedo, "envcap_sphere_count": len(sb)}
    defs = {"ENVCAP_DYNAMIC_ENVIRONMENT": "sky_env", "ENVCAP_SPHERE_CAP": 4}
    got = run_glsl(gl_ctx, body, {"x": x, "t": T, "b": B, "nn": N, "v": v}, {"o1": 3, "o2": 3},
                   includes=INCLUDES, defines=defs, uniforms=uni, declarations=ENV_GLSL)
    F = np.stack([T, B, N], axis=1)
    ref = dynamic_terms(x, F, vl, mat, sb, sky_env, cap=4)
    scale = np.abs(ref.blocked).max()
    assert scale > 0.05
    sel5 = np.sort(select_spheres(x, sb, cap=5).t, axis=1)
    clear = np.abs(sel5[:, 3] - sel5[:, 4]) > 1e-4 * sel5[:, 3]
    # measured 2.7e-6 of the largest term (float32 angles through the fractions' slopes)
    assert np.abs(got["o1"][clear] - ref.blocked[clear]).max() < 2e-5 * scale
    assert np.abs(got["o2"][clear] - ref.bounced[clear]).max() < 2e-5 * scale
    # the paper's bounce (the horizontal mirror of M) in GLSL and numpy
    k = slice(0, 200)
    paper = run_glsl(gl_ctx, body, {"x": x[k], "t": T[k], "b": B[k], "nn": N[k], "v": v[k]}, {"o1": 3, "o2": 3},
                     includes=INCLUDES, defines=defs | {"ENVCAP_DYNAMIC_BOUNCE_PAPER": 1}, uniforms=uni,
                     declarations=ENV_GLSL)
    refp = dynamic_terms(x[k], F[k], vl[k], mat, sb, sky_env, cap=4, bounce="paper")
    assert np.abs(paper["o2"][clear[k]] - refp.bounced[clear[k]]).max() < 2e-5 * scale
    assert np.abs(refp.bounced - ref.bounced[k]).max() > 1e-3 * scale          # the rules differ
    with pytest.raises(ValueError, match="bounce"):
        dynamic_terms(x[k], F[k], vl[k], mat, sb, sky_env, bounce="mirror")
    # the static + dynamic shading, and nothing without spheres
    lit = shade_with_spheres(sky_env, x[:10], F[:10], vl[:10], mat, sb, cap=4)
    static = shade_lafortune(sky_env, vl[:10], F[:10], mat.rho_d, mat.C, mat.w, mat.rho_s)
    np.testing.assert_allclose(lit, static - ref.blocked[:10] + ref.bounced[:10], rtol=1e-12)
    none = dynamic_terms(x[:10], F[:10], vl[:10], mat, SphereBuffer(np.zeros((0, 3)), [], np.zeros((0, 3))), sky_env)
    assert np.all(none.blocked == 0) and np.all(none.bounced == 0)
    np.testing.assert_array_equal(mirror([[1.0, 2.0, 3.0]]), [[-1.0, 2.0, -3.0]])


def test_a_containing_sphere_blocks_everything():
    """Inside a sphere the whole environment of every lobe is blocked: blocked = Eq. 3 (for a
    constant environment, where the lookup direction does not matter)."""
    sb = SphereBuffer([[0.0, 1.0, 0.0]], [2.0], [[0.5, 0.5, 0.5]])
    env = lambda d, w: np.ones(d.shape[:-1] + (3,))   # noqa: E731
    mat = Lafortune((0.4, 0.5, 0.6), ((-1.0, -1.0, 1.0),), (20.0,), ((0.2, 0.2, 0.2),))
    F = np.eye(3)[None]
    vl = np.array([[0.3, 0.0, 0.954]])
    for form in ("envcap", "paper"):
        d = dynamic_terms(np.zeros((1, 3)), F, vl, mat, sb, env, form=form)
        static = shade_lafortune(env, vl, F, mat.rho_d, mat.C, mat.w, mat.rho_s)
        np.testing.assert_allclose(d.blocked, static, rtol=1e-9)
        np.testing.assert_allclose(d.bounced, 0.5 * static, rtol=1e-9)
        np.testing.assert_allclose(d.union, 1.0)
    assert cap_half_angle(0.0) == pytest.approx(math.pi / 2)
