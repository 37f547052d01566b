"""The opt-in ``inverse_distance`` writer (``envcap capture --inverse-distance``): the baked set's
``inverse_distance.ktx2`` is an R16F cube-map array holding the runtime's ``inverse_distance`` of
the set's distance channel (read back by our reader and by ktx-parse, bit for bit), an engine that
uploads its bytes as ``R16F`` gets ``envcap_depth_refine``'s numpy twin out of the GLSL, and sets
written without it are byte-identical to today's."""

import ctypes
import dataclasses
import hashlib
import json
import struct

import numpy as np
import pytest
from runtime_fixtures import DECL
from test_ktx2_conformance import SPEC_KEYS, ktx_parse

from envcap.cli import main
from envcap.formats import inverse_distance_writer as idw
from envcap.formats.ktx2 import read_ktx2, write_ktx2
from envcap.formats.registry import WRITERS, default_writer_names
from envcap.gpu.context import RawGL
from envcap.gpu.glsl_harness import run_glsl
from envcap.probeset.store import read_probe_set, write_probe_set
from envcap.runtime.methods import depth_refine as dr
from envcap.runtime.street import RuntimeStreet

UNIT = 5


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """The canyon at 16^2, 3 probes, baked by the CLI with --inverse-distance (and --exr, so that the
    set reads back with its distance channel); ~0.5 s."""
    out = tmp_path_factory.mktemp("idw") / "set"
    assert main(["capture", "canyon", "--resolution", "16", "--spacing", "200", "--quiet", "--exr",
                 "--inverse-distance", "--out", str(out)]) == 0
    return out, read_probe_set(out)


def test_inverse_distance_file_holds_the_runtime_texture(baked):
    out, ps = baked
    files = json.loads((out / "manifest.json").read_text())["files"]
    assert files["inverse_distance"] == "inverse_distance.ktx2"
    assert "inverse_distance" in WRITERS and "inverse_distance" not in default_writer_names()
    want = dr.inverse_distance(ps.distance)                        # float32 (L, 6, N, N), 1/m
    L, n = ps.layer_count, ps.resolution
    assert L == 3 and n == 16 and (want == 0).any() and (want > 0.05).any()      # sky and near walls
    [lev], info = read_ktx2(out / "inverse_distance.ktx2")
    assert (info["fmt"], info["vk_format"], info["layers"], info["size"], info["level_count"]) == ("r16f", 76, L, n, 1)
    assert not info["premultiplied"] and lev.shape == (L, 6, n, n, 1)
    got = lev[..., 0]
    np.testing.assert_array_equal(got, want.astype(np.float16).astype(np.float32))   # round to nearest half
    assert np.all(np.abs(got - want) <= 2.0 ** -11 * want) and np.array_equal(got == 0, want == 0)
    assert np.array_equal(got == 0, ps.levels[0][..., 3] == 0)  # sky exactly where the probes see it
    # the independent reader: header, DFD (one signed-float R sample), spec keys only, the texels' bytes
    [f] = ktx_parse(out / "inverse_distance.ktx2")
    assert (f["vkFormat"], f["typeSize"], f["pixelWidth"], f["pixelHeight"], f["pixelDepth"], f["layerCount"],
            f["faceCount"], f["levelCount"], f["supercompressionScheme"]) == (76, 2, n, n, 0, L, 6, 1, 0)
    [dfd] = f["dfd"]
    assert (dfd["colorModel"], dfd["transferFunction"], dfd["flags"], dfd["bytesPlane"][0]) == (1, 1, 0, 2)
    assert [(s["bitOffset"], s["bitLength"], s["channelType"]) for s in dfd["samples"]] == [(0, 15, 0xC0)]
    assert set(f["keyValue"]) <= SPEC_KEYS and f["rewriteIdentical"]
    assert f["levels"][0]["sha256"] == hashlib.sha256(want.astype("<f2").tobytes()).hexdigest()


def test_writer_pins_the_runtime_values_and_refuses_a_set_without_distance(baked, tmp_path):
    hard = np.array([0.0, 2.0, np.inf, -np.inf, np.nan, -1.0, 1e6, 1e5, 99_999.0, 1e-7, 3.0e-3])
    want = np.array([0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0 / 99_999.0, 1e7, 1.0 / 3.0e-3], np.float32)
    np.testing.assert_array_equal(dr.inverse_distance(hard), want)   # hand-derived: 0 = sky, Inf, NaN, <= 0, >= 1e5 m
    assert idw.inverse_distance is dr.inverse_distance                 # the writer stores what the runtime reads
    ps = dataclasses.replace(baked[1], distance=None)
    with pytest.raises(ValueError, match="distance channel"):
        write_probe_set(tmp_path / "nodist", ps, exr=False, previews=False, writers=["ktx2", "inverse_distance"])
    assert not (tmp_path / "nodist").exists()


def test_sets_without_the_option_are_unchanged(canyon_probe_set, tmp_path):
    ps = canyon_probe_set
    plain = write_probe_set(tmp_path / "plain", ps, exr=False, previews=False, writers=["ktx2"])
    withi = write_probe_set(tmp_path / "with", ps, exr=False, previews=False, writers=["ktx2", "inverse_distance"])
    a, b = (json.loads((d / "manifest.json").read_text()) for d in (plain, withi))
    assert "inverse_distance" not in a["files"] and b["files"].pop("inverse_distance") == "inverse_distance.ktx2"
    assert a == b and not (plain / "inverse_distance.ktx2").exists()
    for name in ("probes.ktx2", "sky.ktx2"):
        assert (plain / name).read_bytes() == (withi / name).read_bytes()
    # one-channel KTX2: exact r32f round trip, premultiplied refused (no alpha), channel count checked
    cube = [np.arange(6 * 16, dtype=np.float32).reshape(6, 4, 4, 1), np.ones((6, 2, 2, 1), np.float32)]
    levels, info = read_ktx2(write_ktx2(tmp_path / "r.ktx2", cube, layered=False, fmt="r32f"))
    assert info["fmt"] == "r32f" and all(np.array_equal(x, y) for x, y in zip(levels, cube))
    with pytest.raises(ValueError, match="alpha"):
        write_ktx2(tmp_path / "p.ktx2", cube, layered=False, fmt="r16f", premultiplied=True)
    with pytest.raises(ValueError, match=r"\(6, N, N, 1\)"):
        write_ktx2(tmp_path / "c.ktx2", [np.zeros((6, 4, 4, 4), np.float32)], layered=False, fmt="r16f")


def test_city_bakes_refuse_the_option(tmp_path, capsys):
    assert main(["capture", "canyon", "--out", str(tmp_path / "c"), "--workers", "1", "--inverse-distance"]) == 2
    assert "--inverse-distance is for one scene's probe set" in capsys.readouterr().err
    assert not (tmp_path / "c").exists()


def upload_r16f(path):
    """The file's level 0 bytes uploaded as-is, as an engine would: GL_R16F cube-map array, RED /
    HALF_FLOAT, NEAREST; returns (gl, texture name)."""
    b = path.read_bytes()
    n, layers = struct.unpack_from("<I", b, 20)[0], struct.unpack_from("<I", b, 32)[0]
    off, length = struct.unpack_from("<2Q", b, 80)
    data = ctypes.create_string_buffer(b[off:off + length], length)
    gl, tex = RawGL(), ctypes.c_uint(0)
    gl.clear_errors()
    gl.glGenTextures(1, ctypes.byref(tex))
    gl.glBindTexture(0x9009, tex.value)                              # GL_TEXTURE_CUBE_MAP_ARRAY
    gl.glTexStorage3D(0x9009, 1, 0x822D, n, n, 6 * layers)           # GL_R16F
    gl.glPixelStorei(0x0CF5, 2)                                      # GL_UNPACK_ALIGNMENT
    gl.glTexSubImage3D(0x9009, 0, 0, 0, 0, n, n, 6 * layers, 0x1903, 0x140B, data)   # GL_RED, GL_HALF_FLOAT
    for p in (0x2801, 0x2800):                                       # MIN / MAG filter: NEAREST
        gl.glTexParameteri(0x9009, p, 0x2600)
    gl.check("R16F upload")
    return gl, tex


def test_glsl_depth_refine_reads_the_file_like_the_twin(baked, gl_ctx):
    """envcap_depth_refine with the texture uploaded from the file's bytes against the numpy twin on
    the values read back; planes moved 2 m in so that most lookups refine (the texture matters)."""
    out, ps = baked
    inv = read_ktx2(out / "inverse_distance.ktx2")[0][0][..., 0]
    st = RuntimeStreet.from_manifest(ps.manifest.streets[0], "fitted")
    st = dataclasses.replace(st, planes=st.planes + np.array([2.0, -2.0, 0.0]))
    rng = np.random.default_rng(7)
    m = 3000
    lo, hi = st.positions[:, 0].min() - 20, st.positions[:, 0].max() + 20
    x = np.c_[rng.uniform(lo, hi, m), rng.uniform(0.2, 6.0, m), rng.uniform(-5.5, 5.5, m)]
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    x32, d32 = (np.asarray(a, np.float32).astype(np.float64) for a in (x, d))
    uni = st.uniforms(ps.manifest.lobe_powers)
    gl, tex = upload_r16f(out / "inverse_distance.ktx2")
    try:
        gl.glActiveTexture(0x84C0 + UNIT)
        gl.glBindTexture(0x9009, tex.value)
        got = run_glsl(gl_ctx, "int k = envcap_nearest_probe(x[i].xyz[envcap_street.along], envcap_street.along_s, "
                               "envcap_street.count);\n"
                               "o[i] = envcap_depth_refine(dist, envcap_street.pos[k].w, x[i].xyz, d[i].xyz, "
                               "envcap_street.pos[k].xyz, envcap_street.planes[k], envcap_street.along);",
                       {"x": uni.to_local(x), "d": d}, {"o": 4}, uniforms=uni.values(),
                       declarations=DECL + f"\nlayout(binding = {UNIT}) uniform samplerCubeArray dist;\n",
                       includes=("runtime/envcap_depth_refine.glsl",))["o"]
    finally:
        gl.glDeleteTextures(1, ctypes.byref(tex))
    i = st.nearest(x)
    args = (st.positions[i], st.lookup_planes[i], st.along)
    r, q = dr.depth_refine(x32, d32, *args, inv, st.layers[i])
    r_blind, _ = dr.depth_refine(x32, d32, *args, np.zeros_like(inv), st.layers[i])   # a texture of sky only
    assert np.all(np.isfinite(got))
    bad = (np.abs(got[:, :3] - r).max(axis=1) > 2e-4) | (np.abs(np.log(got[:, 3] / q)) > 2e-3)
    assert bad.mean() < 0.01, bad.mean()                  # nearest-texel edges in float32 (16^2 faces)
    moved = np.abs(r - r_blind).max(axis=1) > 1e-3
    assert moved.mean() > 0.3, moved.mean()               # the distances moved the hits
