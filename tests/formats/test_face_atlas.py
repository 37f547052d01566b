"""envcap.formats.face_atlas + shaders/runtime/envcap_face_atlas.glsl: the WebGL2 probe layout (a
2D array of face atlases with seam borders) sampled in GL gives the cube-map-array lookups, and
the full runtime gives the same numbers on either layout, within the tolerance stated in
docs/engines.md."""

import moderngl
import numpy as np
import pytest

from envcap.core import cube_sampling as cs
from envcap.formats.face_atlas import bordered_level, face_atlas, face_atlas_layout, face_size_of_width
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.glsl_harness import run_glsl

from runtime_fixtures import ARGS, DECL, probe_set

ATLAS_UNIT = 5
ATLAS_DECL = f"layout(binding = {ATLAS_UNIT}) uniform sampler2DArray atlas;\n"
ATLAS_DEFINES = {"ENVCAP_PROBES_SAMPLER": "sampler2DArray",  # what the webgl2 prologue defines
                 "ENVCAP_PROBES_LOD(p, d, l, z)": "envcap_face_atlas_lod(p, d, l, z)"}
# Stated tolerance, atlas vs cube array, as a fraction of the largest texel value: the border
# corners are means of three texels rounded to half floats (2^-11 relative), and a corner has
# bilinear weight <= 1/4 at the cube corner: 2^-11 / 4 = 1.2e-4; plus float32 filtering noise.
TOL = 1.5e-4


def atlas_texture(ctx, atlas):
    """``(L, H, W, 4)`` float16 atlas -> a LINEAR, CLAMP_TO_EDGE, one-level GL 2D array texture."""
    tex = ctx.texture_array((atlas.shape[2], atlas.shape[1], atlas.shape[0]), 4,
                            data=np.ascontiguousarray(atlas).tobytes(), dtype="f2" if atlas.dtype == np.float16 else "f4")
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = False
    return tex


def test_layout_by_hand_and_size_from_width():
    lay = face_atlas_layout(8, 4)      # faces 8, 4, 2, 1
    assert (lay.width, lay.height) == (10 + 6, 6 + 4 + 3)
    assert lay.origins == ((0, 0), (10, 0), (10, 6), (10, 10)) and lay.face_sizes == (8, 4, 2, 1)
    assert face_atlas_layout(256, 9).height == 255 + 2 * 8 and face_atlas_layout(256, 2).height == 258
    assert [face_size_of_width(face_atlas_layout(n, 1).width) for n in range(1, 600)] == list(range(1, 600))
    with pytest.raises(ValueError, match="not the width"):
        face_size_of_width(9)           # between N = 3 (8) and N = 4 (10)
    with pytest.raises(ValueError, match="at most 4"):
        face_atlas_layout(8, 5)


def test_glsl_size_from_width_matches(gl_ctx):
    widths = np.array([face_atlas_layout(n, 1).width for n in range(1, 300)])
    got = run_glsl(gl_ctx, "o[i] = vec4(float(envcap_face_atlas_size(int(w[i].x))));", {"w": widths}, {"o": 1},
                   includes=("runtime/envcap_face_atlas.glsl",))["o"][:, 0]
    np.testing.assert_array_equal(got, np.arange(1, 300))


def test_border_is_the_adjacent_face_texel():
    # +X face (0), column -1 (s < 0) is the +Z face's last column (u = +1 side), same rows:
    # +X at u = -1 - e is direction (1, -v, 1 + e) -> +Z face, u = 1/(1 + e) -> column n - 1.
    n = 4
    lv = np.arange(6 * n * n, dtype=np.float64).reshape(1, 6, n, n, 1)
    b = bordered_level(lv)
    np.testing.assert_array_equal(b[0, 0, 1:-1, 0, 0], lv[0, 4, :, n - 1, 0])
    # corner: mean of the three texels meeting at the cube corner
    assert b[0, 0, 0, 0, 0] == pytest.approx((b[0, 0, 1, 1, 0] + b[0, 0, 0, 1, 0] + b[0, 0, 1, 0, 0]) / 3)


def _directions(rng, n_random, n_edge):
    d = rng.normal(size=(n_random, 3))
    e = rng.uniform(-1, 1, (2 * n_edge, 3))                        # near edges, and near corners
    e[:n_edge, 0] = 1.0
    e[:n_edge, 1] = rng.choice([-1.0, 1.0], n_edge) * (1 - rng.uniform(0, 1e-3, n_edge))
    e[n_edge:] = rng.choice([-1.0, 1.0], (n_edge, 3)) * (1 - rng.uniform(0, 0.05, (n_edge, 3)))
    d = np.concatenate([d, e])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_atlas_lookup_matches_the_cube_array_lookup_in_gl(gl_ctx):
    rng = np.random.default_rng(1)
    n, k_levels, layers = 8, 4, 2
    levels = [rng.uniform(0, 1, (layers, 6, max(1, n >> k), max(1, n >> k), 4)).astype(np.float16).astype(np.float32)
              for k in range(k_levels)]
    d = _directions(rng, 6000, 2000)
    lod = rng.uniform(0, k_levels - 1, len(d))
    lod[:300], lod[300:600] = 0.0, k_levels - 1
    layer = rng.integers(0, layers, len(d)).astype(np.float64)
    pt = CubeArrayTexture(levels, internal="rgba16f")
    results = {}
    for dtype in (np.float16, np.float32):
        tex = atlas_texture(gl_ctx, face_atlas(levels, dtype))
        tex.use(ATLAS_UNIT)
        results[dtype] = run_glsl(gl_ctx, "o[i] = textureLod(probes, vec4(d[i].xyz, q[i].x), q[i].y);\n"
                                  "p[i] = envcap_face_atlas_lod(atlas, d[i].xyz, q[i].x, q[i].y);",
                                  {"d": d, "q": np.c_[layer, lod]}, {"o": 4, "p": 4}, probes=pt,
                                  includes=("runtime/envcap_face_atlas.glsl",), declarations=ATLAS_DECL)
        tex.release()
    pt.release()
    cube, half, single = results[np.float16]["o"], results[np.float16]["p"], results[np.float32]["p"]
    ref = cs.sample_cube_array(levels, d, layer.astype(int), lod)   # float64 twin of the cube lookup
    print(f"\nface atlas vs cube array (GL): half atlas max {np.abs(half - cube).max():.2e}, "
          f"float32 atlas max {np.abs(single - cube).max():.2e}, cube vs float64 twin {np.abs(cube - ref).max():.2e}")
    assert np.abs(cube - ref).max() < 2e-6                            # GL cube array == its twin
    assert np.abs(half - cube).max() <= TOL * np.abs(levels[0]).max()  # measured 5.9e-5
    # the float32 atlas (unrounded corner means) agrees to filtering noise: the half-float
    # rounding of the corner means is the whole difference
    assert np.abs(single - cube).max() < 2e-6


def test_runtime_on_the_atlas_matches_the_cube_array_runtime(gl_ctx):
    probes, sky, street, powers = probe_set(n=16)
    probes = [p.astype(np.float16).astype(np.float32) for p in probes]
    pt, st = CubeArrayTexture(probes, internal="rgba16f"), cube_texture(gl_ctx, sky)
    tex = atlas_texture(gl_ctx, face_atlas(probes, np.float16))
    uni = street.uniforms(powers)
    rng = np.random.default_rng(3)
    n = 6000
    x = np.c_[rng.uniform(-5, 25, n), rng.uniform(-1, 15, n), rng.uniform(-7, 7, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(np.log(0.1), np.log(1e6), n))
    inputs = {"x": uni.to_local(x), "d": d, "w": w}
    try:
        for fn in ("envcap_sample_nearest", "envcap_sample_blended"):
            body = f"o[i] = vec4({fn}(probes, sky, x[i].xyz, d[i].xyz, w[i].x, {ARGS}), 0);"
            cube = run_glsl(gl_ctx, body, inputs, {"o": 3}, uniforms=uni.values(), declarations=DECL, probes=pt, sky=st)["o"]
            tex.use(ATLAS_UNIT)
            atlas = run_glsl(gl_ctx, body.replace("(probes,", "(atlas,"), inputs, {"o": 3}, uniforms=uni.values(),
                             includes=("runtime/envcap_face_atlas.glsl", "runtime/envcap_runtime.glsl"),
                             defines=ATLAS_DEFINES, declarations=ATLAS_DECL + DECL, sky=st)["o"]
            assert np.all(np.isfinite(atlas))
            print(f"\n{fn}: atlas vs cube array max {np.abs(atlas - cube).max():.2e} (results up to "
                  f"{np.abs(cube).max():.3g}, texels up to {np.abs(probes[0]).max():.3g})")
            # same tolerance, relative to the largest probe texel (the sky term is shared)
            assert np.abs(atlas - cube).max() <= TOL * np.abs(probes[0]).max(), fn   # measured 7.4e-5 (max 3.0)
    finally:
        pt.release()
        st.release()
        tex.release()
