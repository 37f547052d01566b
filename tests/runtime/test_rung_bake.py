"""A probe set baked with a rung ladder (``bake_probe_set(ladder_mode=...)``, ``envcap capture
--ladder``): the files (our reader and ktx-parse, an independent one), the read-back lookups
against the float64 exact cos^w lobe, and the GLSL rung street variant
(``shaders/runtime/envcap_rung_street.glsl``) on the baked KTX2 against the numpy twin."""

import hashlib
import json
import shutil
import subprocess
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from envcap.core import cube_sampling
from envcap.core.color import luminance
from envcap.formats.ktx2 import read_ktx2
from envcap.gpu.cube_array import CubeArrayTexture
from envcap.gpu.glsl_harness import run_glsl
from envcap.prefilter.exact import convolve_exact_dirs
from envcap.runtime.chains import ProbeChains, SkyChain
from envcap.runtime.rungs import rung_street_uniforms
from envcap.runtime.sampling import composite, sample_sky, sample_street
from envcap.runtime.street import RuntimeStreet

N = 16                       # rung ladder (16, 8): 8 half-octave rungs, w = 766 .. 1
KTX_PARSE = Path(__file__).resolve().parents[1] / "formats" / "ktx_parse" / "read_ktx2.mjs"


@pytest.fixture(scope="module")
def baked(gl_ctx, tmp_path_factory):
    """(read back, directory): ``envcap capture canyon --ladder half_octave``, two probes (x = -150,
    150) of 16^2 faces."""
    from envcap.cli import main
    from envcap.probeset.store import read_probe_set

    path = tmp_path_factory.mktemp("rungs") / "set"
    assert main(["capture", "canyon", "--out", str(path), "--resolution", str(N), "--spacing", "300",
                 "--ladder", "half_octave", "--quiet"]) == 0
    gl_ctx.__enter__()                    # the CLI made and released a context of its own
    return read_probe_set(path), path


def _dirs(rng, m):
    d = rng.normal(size=(m, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_files_manifest_and_an_independent_reader(baked, canyon_probe_set):
    back, path = baked
    m = json.loads((path / "manifest.json").read_text())
    lad = back.manifest.ladder.rung_ladder()
    assert m["ladder"]["mode"] == "half_octave" and m["ladder"]["per_level"] == 4 and m["ladder"]["sizes"] == [16, 8]
    assert m["lobes"]["powers"] == [lad.powers[0], lad.powers[4]]           # layer r = 0 of each level
    assert "ladder" not in canyon_probe_set.manifest.to_json()             # the paper's chain: no key, same bytes
    schema = json.loads((Path(__file__).resolve().parents[2] / "docs" / "manifest.schema.json").read_text())
    jsonschema.validate(m, schema)                                         # the published schema knows the key
    probes, pinfo = read_ktx2(path / "probes.ktx2")
    sky, sinfo = read_ktx2(path / "sky.ktx2")
    assert (pinfo["layers"], pinfo["level_count"], sinfo["layers"], sinfo["level_count"]) == (8, 2, 4, 2)
    for j in range(2):
        np.testing.assert_array_equal(back.rungs[j], probes[j])
        np.testing.assert_array_equal(back.sky_rungs[j], sky[j])
    np.testing.assert_array_equal(back.levels[0], probes[0][0::4])          # rung 0: the capture
    np.testing.assert_array_equal(back.sky_levels[1], sky[1][0])
    node = shutil.which("node")
    if node is None:
        pytest.fail("node is needed to run ktx-parse (tests/formats/ktx_parse): apt-get install nodejs")
    out = subprocess.run([node, str(KTX_PARSE), str(path / "probes.ktx2"), str(path / "sky.ktx2")],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    fp, fs = [json.loads(line) for line in out.stdout.splitlines()]
    assert (fp["vkFormat"], fp["faceCount"], fp["layerCount"], fp["levelCount"], fp["pixelWidth"]) == (97, 6, 8, 2, 16)
    assert (fs["vkFormat"], fs["faceCount"], fs["layerCount"], fs["levelCount"]) == (109, 6, 4, 2)
    assert fp["rewriteIdentical"] and fs["rewriteIdentical"]
    for j in range(2):                                                     # the same texels, bit for bit
        assert fp["levels"][j]["sha256"] == hashlib.sha256(np.asarray(back.rungs[j], "<f2").tobytes()).hexdigest()
        assert fs["levels"][j]["sha256"] == hashlib.sha256(np.asarray(back.sky_rungs[j], "<f4").tobytes()).hexdigest()


def test_read_back_lookups_hold_the_exact_lobe(baked):
    # The runtime twin on the read-back set (rungs composited over the sky's rungs) against the
    # float64 exact cos^w lobe of the capture over the sky, at the probe's own position.
    back, _ = baked
    chains = ProbeChains.from_probe_set(back)
    sky = SkyChain(back.sky_rungs, chains.ladder)
    cap = np.asarray(back.levels[0][1], np.float64)           # the probe at x = 150
    sky0 = np.asarray(back.sky_levels[0], np.float64)
    env = cap + (1.0 - cap[..., 3:4]) * sky0
    d = _dirs(np.random.default_rng(7), 512)
    errs, errs_paper = [], []
    # control: the r = 0 layers alone (one lobe per level, as a plain chain) are much further off
    plain = ProbeChains([np.asarray(a) for a in back.levels], back.manifest.lobe_powers)
    for w in np.logspace(0, np.log10(30.0), 7):               # rungs held at >= 1.4 texels at 16^2 (w <= 30)
        got = composite(chains.fetch(d, np.ones(len(d)), w), sample_sky(sky, d, w, chains.xk))
        ref = luminance(convolve_exact_dirs(env, w, d))
        errs.append(np.sqrt(np.mean((luminance(got) - ref) ** 2) / np.mean(ref ** 2)))
        gp = composite(plain.fetch(d, np.ones(len(d)), w), sample_sky(SkyChain(back.sky_levels), d, w, plain.xk))
        errs_paper.append(np.sqrt(np.mean((luminance(gp) - ref) ** 2) / np.mean(ref ** 2)))
    errs, errs_paper = np.array(errs), np.array(errs_paper)
    # docs/lobes.md, "Baked rung ladders": at 16^2 for w in [1, 30], measured median 0.9 %, max 2.5 %
    # (the r = 0 chain: median 11 %)
    assert np.median(errs) < 0.015 and errs.max() < 0.04, errs
    assert np.median(errs_paper) > 3 * np.median(errs), (errs, errs_paper)


def test_read_back_lookups_hold_the_exact_lobe_up_to_the_mirror(baked):
    # The top of the ladder (docs/lobes.md): from rung 1's power to the mirror, the read-back rungs
    # composited over the sky's against the float64 exact lobe of the capture over the sky; the
    # control reads rung 0 bilinearly (the lookup before) past rung 0's power.
    back, _ = baked
    chains = ProbeChains.from_probe_set(back)
    sky = SkyChain(back.sky_rungs, chains.ladder)
    cap = np.asarray(back.levels[0][1], np.float64)
    sky0 = np.asarray(back.sky_levels[0], np.float64)
    env = cap + (1.0 - cap[..., 3:4]) * sky0
    d = _dirs(np.random.default_rng(11), 1024)
    w1, w0 = chains.ladder.powers[1], chains.ladder.powers[0]
    errs, before = {}, {}
    for w in (w1, np.sqrt(w1 * w0), w0, 3 * w0, 1e5, 1e7, np.inf):
        ref = luminance(convolve_exact_dirs(env, min(w, 1e300), d))
        got = composite(chains.fetch(d, np.ones(len(d)), w), sample_sky(sky, d, w, chains.xk))
        errs[w] = np.sqrt(np.mean((luminance(got) - ref) ** 2) / np.mean(ref ** 2))
        if w >= w0:
            bil = composite(cube_sampling.bilinear(back.rungs[0], d, np.full(len(d), 4)),
                            cube_sampling.bilinear(back.sky_rungs[0], d, np.zeros(len(d), int)))
            before[w] = np.sqrt(np.mean((luminance(bil) - ref) ** 2) / np.mean(ref ** 2))
    e = np.array(list(errs.values()))
    # measured at 16^2: 4.5 % at rung 1 (its own bilinear read), 3.7 / 1.9 / 1.3 % at sqrt(w_1 w_0),
    # w_0, 3 w_0, 4e-6 at 1e5, 0 at 1e7 and the mirror; rung 0 read bilinearly: 9.2 / 18 / 23 / 23 / 23 %
    assert e.max() < 0.05 and errs[1e5] < 1e-3 and errs[1e7] < 1e-9 and errs[np.inf] < 1e-9, errs
    assert all(before[w] > 3 * errs[w] for w in before), (before, errs)


def test_glsl_rung_street_on_the_baked_textures_matches_numpy(baked, gl_ctx):
    back, _ = baked
    chains = ProbeChains.from_probe_set(back)
    lad = chains.ladder
    sky = SkyChain(back.sky_rungs, lad)
    street = RuntimeStreet.from_manifest(back.manifest.streets[0])
    uni = street.uniforms(back.manifest.lobe_powers)
    rng = np.random.default_rng(8)
    m = 4000
    x = np.c_[rng.uniform(-180, 180, m), rng.uniform(0, 12, m), rng.uniform(-5, 5, m)]
    d = _dirs(rng, m)
    w = np.exp(rng.uniform(np.log(0.3), np.log(3e4), m))
    w[:4] = [0.0, np.inf, lad.powers[5], lad.powers[-1]]
    pt = CubeArrayTexture([np.asarray(a, np.float32) for a in back.rungs])
    st = CubeArrayTexture([np.asarray(a, np.float32) for a in back.sky_rungs])
    try:
        st.use(5)
        got = {fn: run_glsl(gl_ctx, f"o[i] = vec4({fn}(probes, rsky, x[i].xyz, d[i].xyz, w[i].x, envcap_street), 0);",
                            {"x": uni.to_local(x), "d": d, "w": np.where(np.isfinite(w), w, 3e38)}, {"o": 3},
                            uniforms=rung_street_uniforms(uni, lad), includes=("runtime/envcap_rung_street.glsl",),
                            declarations="uniform EnvcapStreet envcap_street;\n"
                                         "layout(binding = 5) uniform samplerCubeArray rsky;\n",
                            probes=pt)["o"]
               for fn in ("envcap_sample_nearest", "envcap_sample_blended")}
    finally:
        pt.release()
        st.release()
    f32 = lambda a: np.asarray(a, np.float32).astype(np.float64)   # noqa: E731
    for fn, method in (("envcap_sample_nearest", "planes_mip"), ("envcap_sample_blended", "blend")):
        ref = sample_street(chains, sky, street, f32(x), f32(d), f32(np.where(np.isfinite(w), w, 3e38)), method)
        assert np.all(np.isfinite(got[fn]))
        # float32 lookup vectors and rung positions, as the paper chain's GLSL test (4e-6 of the largest value)
        np.testing.assert_allclose(got[fn], ref, rtol=0, atol=4e-6 * np.abs(ref).max(), err_msg=fn)


@pytest.mark.parametrize("mutate,msg", [
    (lambda m: m["ladder"].update(mode="third_octave"), "ladder.mode must be one of"),
    (lambda m: m["ladder"].update(per_level=2), "ladder.mode must be one of"),
    (lambda m: m["ladder"].update(sizes=[16, 4]), "ladder"),
    (lambda m: m["ladder"]["powers"].reverse(), "strictly decreasing"),
    (lambda m: m["ladder"].pop("rule"), "missing key 'rule'"),
])
def test_the_manifest_refuses_a_bad_ladder(baked, mutate, msg):
    from envcap.probeset.manifest import Manifest, ManifestError

    m = baked[0].manifest.to_json()
    Manifest.from_json(json.loads(json.dumps(m)))          # the baked one is valid
    mutate(m)
    with pytest.raises(ManifestError, match=msg):
        Manifest.from_json(m)


def test_a_bad_ladder_mode_is_refused_before_any_work():
    from envcap.probeset.bake import bake_probe_set
    from envcap.scene import load_scene

    with pytest.raises(ValueError, match="ladder mode"):
        bake_probe_set(load_scene("canyon"), resolution=8, spacing=300.0, ladder_mode="quarter")
    with pytest.raises(ValueError, match="needs filtered levels"):
        bake_probe_set(load_scene("canyon"), resolution=8, spacing=300.0, ladder_mode="octave", filter_levels=False)


def test_capture_cli_refuses_a_ladder_for_a_city_bake(tmp_path, capsys):
    from envcap.cli import main

    assert main(["capture", "canyon", "--out", str(tmp_path / "c"), "--ladder", "octave", "--workers", "2"]) == 2
    assert "--ladder is for one scene's probe set" in capsys.readouterr().err
