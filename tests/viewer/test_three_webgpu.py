"""three.js on WebGPU (three_webgpu.html: three.js r187's WebGPURenderer device, probes.ktx2 as a
cube-map array, the runtime in WGSL) in headless Chromium (WebGPU on SwiftShader): the same pixel
and orientation checks as the WebGL2 example's (tests/journeys/test_journey_engine.py): the
background pixel for pixel against the numpy twin through the page's tone map, lookups mirrored
in x or z far off, the sky not black, the spheres drawn and the diffuse ones the twin's colors."""

import base64
import io

import numpy as np
import pytest
from PIL import Image

from envcap.probeset.store import read_probe_set
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet
from envcap.viewer import ViewerSite, serve
from envcap.viewer.browser import find_chromium
from envcap.viewer.webgpu_page import WGSL_PATH

CAPTION_ROWS = 40


def tonemap(L, exposure):
    c = L * exposure
    return 255.0 * (c / (1.0 + c)) ** (1.0 / 2.2)


def pixel_rays(view, cols, rows):
    w, h = view["width"], view["height"]
    fx, fy = (np.asarray(cols) + 0.5) / w * 2 - 1, (h - 1 - np.asarray(rows) + 0.5) / h * 2 - 1
    fx = fx * w / h
    r = np.array(view["rot"], np.float64).reshape(3, 3).T
    d = np.stack([fx * view["tanHalfFov"], fy * view["tanHalfFov"], -np.ones_like(fx)], -1) @ r.T
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def sphere_hits(view, d):
    o = np.array(view["position"])
    best, idx = np.full(len(d), np.inf), np.full(len(d), -1)
    for k, s in enumerate(view["spheres"]):
        oc = o - np.array(s["center"])
        b = d @ oc
        disc = b * b - (oc @ oc - s["radius"] ** 2)
        t = -b - np.sqrt(np.maximum(disc, 0))
        hit = (disc > 0) & (t > 0) & (t < best)
        best[hit], idx[hit] = t[hit], k
    return idx, o + best[:, None] * d


@pytest.fixture(scope="module")
def webgpu_page(viewer_probe_dir):
    if find_chromium() is None:
        pytest.skip("no chromium executable on PATH (.ci/run installs Debian's chromium)")
    pytest.importorskip("websocket")
    from envcap.viewer.browser import Chromium

    server, thread = serve(ViewerSite.open(viewer_probe_dir))
    try:
        with Chromium(480, 320, webgpu=True) as b:
            b.goto(server.url + "three_webgpu.html")
            state = b.evaluate("window.example.ready.then(() => 'ok', e => 'error: ' + e.message)")
            assert state == "ok", (state, b.errors)
            view = b.evaluate("window.example.view()")
            png = base64.b64decode(b.send("Page.captureScreenshot", format="png")["data"])
            caption = b.evaluate("document.getElementById('caption').textContent")
            yield view, np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), np.float64), caption, list(b.errors)
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)


def test_shipped_page_wgsl_is_a_fresh_translation():
    pytest.importorskip("slangpy", reason="pip install '.[test]' (slangpy)")
    from envcap.viewer.webgpu_page import page_wgsl
    assert WGSL_PATH.read_text() == page_wgsl(), "stale: python3 -m envcap.viewer.webgpu_page"


@pytest.mark.slow   # a Chromium with WebGPU, a page, a screenshot: ~10 s on 2 cores
def test_webgpu_page_matches_the_twin(webgpu_page, viewer_probe_dir):
    view, shot, caption, errors = webgpu_page
    assert errors == []
    assert shot.shape[:2] == (view["height"], view["width"])
    assert "three.js r187 on WebGPU" in caption and "cube-map array" in caption, caption
    ps = read_probe_set(viewer_probe_dir, distance=False)
    assert view["probes"] == {"layers": ps.manifest.layer_count, "levels": len(ps.levels), "dimension": "cube-array"}
    street = ps.manifest.streets[0]
    chains = ProbeChains(ps.levels, ps.manifest.lobes.powers)
    runtime = RuntimeStreet.from_manifest(street)

    def lookup(x, d, w):
        return sample_street(chains, ps.sky_levels, runtime, np.float32(x).astype(np.float64),
                             np.float32(d).astype(np.float64), np.full(len(d), float(w)), "planes_mip")

    rows, cols = np.meshgrid(np.arange(4, view["height"] - CAPTION_ROWS, 11), np.arange(4, view["width"], 13), indexing="ij")
    rows, cols = rows.ravel(), cols.ravel()
    d = pixel_rays(view, cols, rows)
    hit, _ = sphere_hits(view, d)
    free = hit < 0
    rows, cols, d = rows[free], cols[free], d[free]
    x = np.broadcast_to(np.array(view["position"]), d.shape)
    got = shot[rows, cols]
    ref = tonemap(lookup(x, d, view["power"]), view["exposure"])
    err = np.abs(got - ref)
    # the WebGL2 example's bound: 8-bit rounding and float32 lookups
    assert err.max() <= 2.0, f"background: {np.count_nonzero(err > 2)} of {err.size} channels off, max {err.max():.1f} levels"
    for axis in (0, 2):
        m = d.copy()
        m[:, axis] *= -1
        mirrored = np.abs(got - tonemap(lookup(x, m, view["power"]), view["exposure"])).mean()
        assert mirrored > 5 * max(err.mean(), 0.2), f"a lookup mirrored in {'xz'[axis // 2]} fits too: {mirrored:.2f}"
    top = (rows < view["height"] // 6) & (d[:, 1] > 0.3)
    assert np.count_nonzero(top) > 10 and got[top].mean() > 60, "black sky"
    r = np.array(view["rot"]).reshape(3, 3)
    for k, s in enumerate(view["spheres"]):
        c = np.array(s["center"])
        e = r @ (c - np.array(view["position"]))
        col = (e[0] / -e[2] / view["tanHalfFov"] * view["height"] / view["width"] + 1) / 2 * view["width"]
        row = view["height"] - (e[1] / -e[2] / view["tanHalfFov"] + 1) / 2 * view["height"]
        pr, pc = int(row), int(col)
        dk = pixel_rays(view, [pc], [pr])
        idx, p = sphere_hits(view, dk)
        assert idx[0] == k, f"sphere {s['name']} is not at pixel ({pc}, {pr})"
        background = tonemap(lookup(np.array([view["position"]]), dk, view["power"]), view["exposure"])[0]
        assert np.abs(shot[pr, pc] - background).max() > 3, f"sphere {s['name']} not drawn"
        if "diffuse" in s["name"]:
            n = (p[0] - c) / s["radius"]
            albedo = {"white diffuse": 0.8, "red diffuse": np.array([0.7, 0.12, 0.1])}[s["name"]]
            want = tonemap(albedo * lookup(p, n[None], 1.0)[0], view["exposure"])
            assert np.abs(shot[pr, pc] - want).max() <= 4, (s["name"], shot[pr, pc], want)
