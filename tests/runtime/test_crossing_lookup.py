"""The lookup inside a crossing (envcap.runtime.crossing_lookup, GLSL runtime/envcap_crossing.glsl):
a street with the crossing probe inserted is the street that had that probe all along (hand-built
reference), a full street drops the far end, and GLSL envcap_crossing_street + the depth-refined
lookup on llvmpipe matches the numpy twin on 12,000 points inside the crossing region and at its
edges, at the crossing probe itself and at along ties."""

import dataclasses

import numpy as np
import pytest
from runtime_fixtures import ARGS, DECL, probe_set

from envcap.core import cube
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime.chains import ProbeChains
from envcap.runtime.crossing_lookup import NO_EXIT, crossing_street, facade_exit, probe_street, street_per_direction
from envcap.runtime.limits import MAX_PROBES
from envcap.runtime.methods.depth_refine import METHOD, inverse_distance
from envcap.runtime.parallax import exit_distance
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet

DIST_UNIT = 5
CDECL = DECL + f"\nlayout(binding = {DIST_UNIT}) uniform samplerCubeArray dist;\nuniform vec4 cprobe;\n"
INCLUDES = ("runtime/envcap_depth_refine.glsl", "runtime/envcap_crossing.glsl")
HALF = 6.0      # the crossing region reaches 6 m along the street either side of the centre probe


def cut(street, idx):
    idx = np.asarray(idx)
    return RuntimeStreet(street.along, street.positions[idx], street.planes[idx], street.layers[idx],
                         street.yaw_deg, street.origin_xz, street.slopes[idx])


@pytest.fixture(scope="module")
def world(gl_ctx):
    probes, sky, street, powers = probe_set(count=4, end=21.0)      # probes at 0, 7, 14, 21 m along x
    d = cube.texel_directions(32).reshape(-1, 3)
    dist = []
    for p in street.positions:
        t = exit_distance(np.broadcast_to(p, d.shape), d, (-6.0, 6.0, 0.0), 0)
        h = p + t[:, None] * d
        dist.append(np.where((t < 1e5) & (h[:, 1] <= 12.0), t, 0.0).reshape(6, 32, 32))
    dist = np.stack(dist)
    inv = inverse_distance(dist)
    tex = CubeArrayTexture([np.concatenate([inv[..., None], np.zeros(inv.shape + (3,), np.float32)], axis=-1)],
                           filter="nearest")
    pt, st = CubeArrayTexture(probes), cube_texture(gl_ctx, sky)
    yield probes, sky, street, powers, dist, pt, st, tex
    for t in (pt, st, tex):
        t.release()


def test_inserted_probe_gives_the_street_that_had_it(world):
    street = world[2]
    base = cut(street, [0, 1, 3])                        # the crossing probe (layer 2) is another street's
    got = crossing_street(base, street.positions[2], 2)
    for f in ("positions", "planes", "layers", "slopes"):
        np.testing.assert_array_equal(getattr(got, f), getattr(street, f))
    assert crossing_street(street, street.positions[2], 2) is street          # the owner: unchanged
    sloped = dataclasses.replace(base, slopes=np.array([0.0, 0.1, 0.0]))
    got = crossing_street(sloped, street.positions[2], 2)                        # nearest along: probe 1 (7 m)
    assert got.slopes[2] == 0.1 and got.planes[2, 2] == pytest.approx(base.planes[1, 2] + 0.1 * 7.0)
    one = probe_street(street, 2)
    assert one.layers.tolist() == [2] and np.array_equal(one.positions[0], street.positions[2])
    assert probe_street(base, 2) is base


def full_street():
    n = MAX_PROBES
    pos = np.c_[np.arange(n) * 2.0, np.full(n, 2.0), np.zeros(n)]
    planes = np.c_[np.full(n, -5.0), np.full(n, 5.0), np.arange(n) * 0.01]
    return RuntimeStreet(0, pos, planes, np.arange(n) + 100)


@pytest.mark.parametrize("s, dropped", [(10.5, -1), (120.5, 0), (63.0, -1)])
def test_a_full_street_drops_its_far_end_in_glsl_and_numpy(gl_ctx, s, dropped):
    """64 probes every 2 m; the crossing probe near the low end, near the high end, and at the
    exact middle (a tie: the last probe goes)."""
    street = full_street()
    got = crossing_street(street, (s, 2.0, 0.0), 7)
    keep = np.delete(np.arange(MAX_PROBES), dropped)
    assert got.layers.size == MAX_PROBES and 7 in got.layers
    assert set(got.layers.tolist()) - {7} == set((street.layers[keep]).tolist())
    uni = street.uniforms((1024.0, 64.0, 1.0), origin=np.zeros(3))
    o = run_glsl(gl_ctx, "EnvcapStreet cs = envcap_crossing_street(envcap_street, cprobe);\nint k = int(i);\n"
                         "o[i] = vec4(cs.along_s[k], cs.pos[k].w, cs.planes[k].z, float(cs.count));",
                 {"k": np.arange(MAX_PROBES)}, {"o": 4}, uniforms={**uni.values(), "cprobe": (s, 2.0, 0.0, 7.0)},
                 declarations=DECL + "\nuniform vec4 cprobe;\n", includes=INCLUDES[1:])["o"]
    np.testing.assert_array_equal(o[:, 3], MAX_PROBES)
    np.testing.assert_array_equal(o[:, 1], got.layers)
    np.testing.assert_allclose(o[:, 0], got.positions[:, 0], rtol=1e-7)
    np.testing.assert_allclose(o[:, 2], got.planes[:, 2], atol=1e-6)


def test_glsl_crossing_lookup_matches_twin(gl_ctx, world):
    """envcap_crossing_street then envcap_sample_depth_refine against crossing_street then the
    numpy depth_refine: 12,000 random points in the crossing region (14 +- 6 m along, the whole
    roadway across, 0.3-3 m high), the region's edges exactly, the crossing probe itself, and
    the along ties with its neighbours (10.5 m, 17.5 m).  Tolerances as the depth_refine test:
    a float32 step across a texel edge may read the neighbouring texel in 0.5 % of lookups."""
    probes, sky, street, powers, dist, pt, st, tex = world
    base = cut(street, [0, 1, 3])
    c = street.positions[2]
    rng = np.random.default_rng(11)
    n = 12_000
    x = np.c_[rng.uniform(c[0] - HALF, c[0] + HALF, n), rng.uniform(0.3, 3.0, n), rng.uniform(-5.9, 5.9, n)]
    hard = np.array([[c[0] - HALF, 1.5, 0.0], [c[0] + HALF, 1.5, 2.0], [c[0] - HALF, 0.3, -6.0], c,
                     [c[0], c[1], -5.0], [10.5, 1.0, 0.0], [17.5, 2.0, -1.0]])
    hx = np.repeat(hard, 8, axis=0)
    x = np.concatenate([x, hx])
    d = rng.normal(size=(len(x), 3))
    d[-len(hx):] = np.tile([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
                            [0.6, -0.0, 0.8], [-0.0, 0.6, -0.8]], (len(hard), 1))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(np.log(1.0), np.log(1e5), len(x)))
    uni = base.uniforms(powers)
    cprobe = tuple(float(v) for v in (c - uni.origin)) + (2.0,)
    tex.use(DIST_UNIT)
    rgb = run_glsl(gl_ctx, "EnvcapStreet cs = envcap_crossing_street(envcap_street, cprobe);\n"
                           f"o[i] = vec4(envcap_sample_depth_refine(probes, sky, dist, x[i].xyz, d[i].xyz, w[i].x, "
                           f"{ARGS.replace('envcap_street', 'cs')}), 0);",
                   {"x": uni.to_local(x), "d": d, "w": w}, {"o": 3}, uniforms={**uni.values(), "cprobe": cprobe},
                   declarations=CDECL, includes=INCLUDES, probes=pt, sky=st)["o"]
    f32 = (lambda a: np.asarray(a, np.float32).astype(np.float64))
    ref = sample_street(ProbeChains(probes, powers, distance=dist), sky, crossing_street(base, c, 2), f32(x), f32(d),
                        f32(w), METHOD)
    assert np.all(np.isfinite(rgb)) and np.all(np.isfinite(ref))
    close = np.abs(rgb - ref).max(axis=1) <= 4e-6 * np.abs(ref).max() + 1e-5 * np.abs(ref).max(axis=1)
    assert close.mean() > 0.995, close.mean()
    # region edges and the crossing probe: all match, but for rays exactly along the street off the
    # probe line (the planes' exit is at infinity there: float32 and float64 refine differently)
    along_ray = np.abs(d[-len(hx):, 0]) == 1.0
    assert close[-len(hx):-16][~along_ray[:-16]].all()
    # the crossing probe is looked up where it is nearest: the same as the street that had it
    full = sample_street(ProbeChains(probes, powers, distance=dist), sky, street, f32(x), f32(d), f32(w), METHOD)
    np.testing.assert_allclose(ref, full, rtol=1e-12, atol=1e-12)


def cross_street():
    """Street B along z through the crossing probe of A (x = 14 m), facades at x = 8 and 20 m."""
    pos = np.array([[14.0, 2.0, -7.0], [14.0, 2.0, 7.0]])
    return RuntimeStreet(2, pos, np.array([[8.0, 20.0, 0.0]] * 2), np.array([0, 3]))


def test_facade_exit_against_hand_values():
    a = cut(full_street(), [0, 1])          # along x, facades z = -5 .. 5
    t = facade_exit(a, (1.0, 2.0, 1.0), np.array([[0, 0, 1.0], [0, 0, -1.0], [0.6, 0, 0.8], [1.0, 0, 0], [0, 1.0, -0.0]]))
    np.testing.assert_allclose(t, [4.0, 6.0, 5.0, NO_EXIT, NO_EXIT])
    assert facade_exit(a, (1.0, 2.0, 7.0), np.array([[0, 0, 1.0]]))[0] == 0.0        # outside: 0
    b = cross_street()
    # a ray along +x from inside both corridors looks down A (B's facade is left first)
    assert street_per_direction([a, b], (10.0, 1.0, 0.0), np.array([[1.0, 0, 0], [0, 0, 1.0], [0, 1.0, 0]])).tolist() == [0, 1, 0]


def test_glsl_direction_choice_matches_twin(gl_ctx, world):
    """envcap_facade_exit of two meeting streets (A along x, B along z; and B turned by 37 deg about a
    far origin) and the lookup of each direction on the street it looks down (depth_refine) against
    the numpy twin: 12,000 points in the crossing region and on its edges, the crossing probe itself,
    axis and -0.0 directions.  Exit distances to float32 precision; choices agree but for near ties."""
    probes, sky, street, powers, dist, pt, st, tex = world
    c = street.positions[2]
    a = crossing_street(cut(street, [0, 1, 3]), c, 2)
    b = crossing_street(cross_street(), c, 2)
    rng = np.random.default_rng(13)
    n = 12_000
    x = np.c_[rng.uniform(8.0, 20.0, n), rng.uniform(0.3, 3.0, n), rng.uniform(-6.0, 6.0, n)]
    hard = np.array([c, [8.0, 1.0, 0.0], [20.0, 1.0, 6.0], [14.0, 1.0, -6.0], [8.0, 0.3, -6.0]])
    hx = np.repeat(hard, 8, axis=0)
    x = np.concatenate([x, hx])
    d = rng.normal(size=(len(x), 3))
    d[-len(hx):] = np.tile([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [-0.0, 0.5, -1],
                            [0.6, -0.0, 0.8], [-0.8, 0.6, -0.0]], (len(hard), 1))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(np.log(1.0), np.log(1e5), len(x)))
    ua, ub = a.uniforms(powers), b.uniforms(powers)
    tex.use(DIST_UNIT)
    body = ("float ta = envcap_facade_exit(envcap_street, xa[i].xyz, d[i].xyz);\n"
            "float tb = envcap_facade_exit(street_b, xb[i].xyz, d[i].xyz);\n"
            "vec3 c = tb > ta ? envcap_sample_depth_refine(probes, sky, dist, xb[i].xyz, d[i].xyz, w[i].x, street_b)\n"
            "                 : envcap_sample_depth_refine(probes, sky, dist, xa[i].xyz, d[i].xyz, w[i].x, envcap_street);\n"
            "o[i] = vec4(c, 0.0); t[i] = vec4(ta, tb, 0.0, 0.0);")
    out = run_glsl(gl_ctx, body, {"xa": ua.to_local(x), "xb": ub.to_local(x), "d": d, "w": w}, {"o": 3, "t": 2},
                   uniforms={**ua.values(), **ub.values("street_b")},
                   declarations=CDECL + "\nuniform EnvcapStreet street_b;\n", includes=INCLUDES, probes=pt, sky=st)
    f32 = (lambda v: np.asarray(v, np.float32).astype(np.float64))
    ta = np.array([facade_exit(a, xi, di[None])[0] for xi, di in zip(f32(x), f32(d))])
    tb = np.array([facade_exit(b, xi, di[None])[0] for xi, di in zip(f32(x), f32(d))])
    for got, ref in ((out["t"][:, 0], ta), (out["t"][:, 1], tb)):
        assert np.all(np.isfinite(got))
        np.testing.assert_allclose(got, np.minimum(ref, NO_EXIT), rtol=2e-5, atol=2e-5)
    pick = (tb > ta).astype(int)
    chains = ProbeChains(probes, powers, distance=dist)
    ref = np.zeros((len(x), 3))
    for j, s in enumerate((a, b)):
        sel = pick == j
        ref[sel] = sample_street(chains, sky, s, f32(x[sel]), f32(d[sel]), f32(w[sel]), METHOD)
    rgb = out["o"]
    assert np.all(np.isfinite(rgb)) and np.all(np.isfinite(ref))
    close = np.abs(rgb - ref).max(axis=1) <= 4e-6 * np.abs(ref).max() + 1e-5 * np.abs(ref).max(axis=1)
    assert close.mean() > 0.995, close.mean()
    assert np.array_equal(pick[-len(hx):], (out["t"][-len(hx):, 1] > out["t"][-len(hx):, 0]).astype(int))
    # on a turned street B (frame yaw 37 deg about a far origin) the exits still agree
    bt = dataclasses.replace(b, yaw_deg=37.0, origin_xz=(350.5, -820.25), along=0,
                             positions=np.c_[b.positions[:, 2], b.positions[:, 1], b.positions[:, 0]],
                             planes=b.planes.copy())
    ubt = bt.uniforms(powers)
    tt = run_glsl(gl_ctx, "o[i] = vec4(envcap_facade_exit(envcap_street, x[i].xyz, d[i].xyz));",
                  {"x": ubt.to_local(x[:2000]), "d": d[:2000]}, {"o": 1}, uniforms=ubt.values(),
                  declarations=CDECL, includes=INCLUDES)["o"][:, 0]
    ref = np.array([facade_exit(bt, xi, di[None])[0] for xi, di in zip(x[:2000], f32(d[:2000]))])
    np.testing.assert_allclose(tt, ref, rtol=1e-3, atol=2e-3)
