"""Street-local runtime uniforms (issue 9, precision far from the origin): StreetUniforms are world
coordinates minus the street's origin (its probes' box center rounded to whole km), subtracted in
float64 and rounded to float32 once; shading points go to GLSL the same way (``to_local``).

Old: the uniforms were world float32; at 10^6 m the float32 twin of the parallax lookup was off
by up to 1.05 deg (an earlier sweep; 42 deg here near the probes, median 0.08 deg) against 0.03 deg at
the origin, and the GLSL output of a street moved by 10^6 m differed from the same street at the
origin.  New: the moved street gives bit-identical uniforms and GLSL output on the km grid, and
the float32 twin's error is that of the origin anywhere.
"""

import numpy as np
import pytest
from runtime_fixtures import ARGS, DECL, probe_set

from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime import parallax as px
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet, StreetUniforms

FAR_KM = np.array([1e6, 0.0, 1e6])
"""A whole number of kilometers: the moved street's origin, exactly."""


def moved(street: RuntimeStreet, offset) -> RuntimeStreet:
    """``street`` translated by ``offset`` (3,) m (facades on the cross axis, ground on y)."""
    off = np.asarray(offset, np.float64)
    c = 2 - street.along
    return RuntimeStreet(street.along, street.positions + off, street.planes + np.array([off[c], off[c], off[1]]),
                         street.layers)


def sweep(n: int, seed: int):
    rng = np.random.default_rng(seed)
    x = np.c_[rng.uniform(-5, 25, n), rng.uniform(-1, 15, n), rng.uniform(-7, 7, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return x, d, np.exp(rng.uniform(np.log(0.1), np.log(1e6), n))


def test_near_the_origin_the_uniforms_are_the_world_float32_ones():
    """Existing outputs unchanged: a street centered within 500 m of the world origin has origin
    (0, 0, 0), and its uniforms are its world coordinates rounded to float32, bit for bit."""
    _, _, street, powers = probe_set(count=3, start=-480.0, end=470.0)
    u = street.uniforms(powers)
    assert np.array_equal(u.origin, np.zeros(3))
    P = street.positions.shape[0]
    assert np.array_equal(u.pos[:P, :3], street.positions.astype(np.float32))
    assert np.array_equal(u.planes[:P, :3], street.planes.astype(np.float32))
    assert np.array_equal(u.along_s[:P], street.positions[:, 0].astype(np.float32))
    assert np.array_equal(u.to_local(street.positions), street.positions.astype(np.float32))


@pytest.mark.parametrize("along", [0, 2])
def test_a_street_moved_by_whole_km_has_bit_identical_uniforms(along):
    _, _, street, powers = probe_set(count=4, along=along, planes=(-4.0, 7.5, 0.25), start=-3.0, end=21.0)
    far = moved(street, FAR_KM)
    u0, u1 = street.uniforms(powers), far.uniforms(powers)
    np.testing.assert_array_equal(u1.origin, FAR_KM)
    for f in StreetUniforms.glsl_fields():
        np.testing.assert_array_equal(getattr(u1, f.name), getattr(u0, f.name), err_msg=f.name)
    x = sweep(1000, 1)[0].astype(np.float32).astype(np.float64)  # exact when moved by 10^6 m in float64
    np.testing.assert_array_equal(u1.to_local(x + FAR_KM), u0.to_local(x))
    # an explicit origin is honored; the old world-frame uniforms are origin=(0, 0, 0)
    old = far.uniforms(powers, origin=np.zeros(3))
    assert np.array_equal(old.pos[:4, :3], far.positions.astype(np.float32))
    assert not np.array_equal(old.pos, u0.pos)


def test_the_float32_twin_is_as_precise_far_away_as_at_the_origin():
    """Angle between the float32 parallax vector and the float64 one (world, exact): world float32
    inputs at 10^6 m (old) against street-local ones (new); points between the probes, anywhere
    in the street.  Off the km grid too (origin at 317 m / 41.5 m from the street's box center)."""
    _, _, street, _ = probe_set(count=3)
    x, d, _ = sweep(100_000, 2)
    i = street.nearest(x)

    def worst(offset, local: bool) -> float:
        s = moved(street, offset)
        xw, p, pl = x + np.asarray(offset), s.positions[i], s.planes[i]
        r64, _ = px.parallax(xw, d, p, pl, s.along)
        o = s.uniforms([1.0]).origin if local else np.zeros(3)
        c = 2 - s.along
        f32 = lambda a: np.asarray(a, np.float64).astype(np.float32)
        r32, _ = px.parallax(f32(xw - o), f32(d), f32(p - o), f32(pl - np.array([o[c], o[c], o[1]])), s.along,
                             dtype=np.float32)
        cos = np.clip(np.sum(r32.astype(np.float64) * r64, axis=-1), -1, 1)
        return float(np.degrees(np.arccos(cos)).max())

    at_origin = worst(np.zeros(3), local=True)
    assert at_origin < 0.05                                   # measured 0.030 deg
    assert worst(FAR_KM, local=False) > 1.0                   # old: measured 41.7 deg (median 0.084)
    for off in (FAR_KM, FAR_KM + [317.25, 2.0, -41.5], np.array([-3.2e6, 50.0, 7.7e5])):
        assert worst(off, local=True) < 0.05                  # measured 0.029-0.030 deg


@pytest.fixture(scope="module")
def textures(gl_ctx):
    probes, sky, street, powers = probe_set()
    pt, st = CubeArrayTexture(probes), cube_texture(gl_ctx, sky)
    yield probes, sky, street, powers, pt, st
    pt.release()
    st.release()


def gl_lookup(ctx, textures, fn, uni: StreetUniforms, x_local, d, w):
    *_, pt, st = textures
    return run_glsl(ctx, f"o[i] = vec4({fn}(probes, sky, x[i].xyz, d[i].xyz, w[i].x, {ARGS}), 0);",
                    {"x": x_local, "d": d, "w": w}, {"o": 3}, uniforms=uni.values(), declarations=DECL,
                    probes=pt, sky=st)["o"]


@pytest.mark.parametrize("fn", ["envcap_sample_nearest", "envcap_sample_blended"])
def test_glsl_output_of_a_street_moved_by_whole_km_is_bit_identical(gl_ctx, textures, fn):
    probes, sky, street, powers = textures[:4]
    x, d, w = sweep(20_000, 3)
    x = x.astype(np.float32).astype(np.float64)  # exact when moved by 10^6 m in float64
    at_origin = gl_lookup(gl_ctx, textures, fn, street.uniforms(powers), street.uniforms(powers).to_local(x), d, w)
    far = moved(street, FAR_KM)
    u = far.uniforms(powers)
    got = gl_lookup(gl_ctx, textures, fn, u, u.to_local(x + FAR_KM), d, w)
    np.testing.assert_array_equal(got, at_origin)
    # the float64 twin (the evaluator's) of the moved street in world coordinates agrees with it
    method = "blend" if fn == "envcap_sample_blended" else "planes_mip"
    f32 = lambda a: np.asarray(a, np.float32).astype(np.float64)
    ref = sample_street(ProbeChains(probes, powers), sky, far, f32(x) + FAR_KM, f32(d), f32(w), method)
    np.testing.assert_allclose(got, ref, rtol=0, atol=4e-6 * np.abs(ref).max())
    # old: world float32 uniforms and shading points differ from the street at the origin
    old = far.uniforms(powers, origin=np.zeros(3))
    before = gl_lookup(gl_ctx, textures, fn, old, old.to_local(x + FAR_KM), d, w)
    assert np.abs(before - at_origin).max() > 100 * 4e-6 * np.abs(ref).max()
