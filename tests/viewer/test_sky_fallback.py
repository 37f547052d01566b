"""The sky on a device without ``OES_texture_float_linear`` (common on phones).  Chromium is made
to hide the extension from the pages (``getExtension`` returns null for it and
``getSupportedExtensions`` leaves it out, so WebGL never enables it), and the pages must still
show the sky:

* a sky that fits half floats (no sun in the map): three.js (``three_probes.js``), the raw WebGL2
  page and the three.js and Babylon.js example pages load it as RGBA16F, linear; its lookups and the example's
  pixels are not black and equal the normal path's (within half-float rounding).  Control: the
  same three.js page told that floats filter (RGBA32F, linear: what it did before) reads a black
  sky, so the hiding is real;
* a sky with the sun in its map (peaks over 65504): RGBA32F with NEAREST filtering and a console
  warning; the sun's energy is kept and its direction is the manifest's.
"""

import base64
import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from viewer_pages import open_page

from envcap.probeset.store import read_probe_set, write_probe_set
from envcap.viewer import ViewerSite, serve
from envcap.viewer.babylon_build import find_babylon

HERE = Path(__file__).resolve().parent
HALF_MAX = 65504.0
HALF_ROUNDING = 1e-3
"""RGBA16F against RGBA32F, relative to each value: half floats round to 2^-11 = 4.9e-4."""
HIDE = """(() => {
  for (const C of [WebGLRenderingContext, WebGL2RenderingContext]) {
    const get = C.prototype.getExtension, list = C.prototype.getSupportedExtensions;
    C.prototype.getExtension = function (name) { return name === "OES_texture_float_linear" ? null : get.call(this, name); };
    C.prototype.getSupportedExtensions = function () { return (list.call(this) || []).filter((n) => n !== "OES_texture_float_linear"); };
  }
})();"""
CHECK_ROUTES = {"/three_check.html": HERE / "three_check.html", "/three_check.js": HERE / "three_check.js"}


@contextlib.contextmanager
def extension_hidden(b):
    """Pages opened in ``b`` inside the block see no OES_texture_float_linear."""
    ident = b.send("Page.addScriptToEvaluateOnNewDocument", source=HIDE)["identifier"]
    try:
        yield b
    finally:
        b.send("Page.removeScriptToEvaluateOnNewDocument", identifier=ident)
        b.goto("about:blank")   # the next page is opened afresh, with the extension


@contextlib.contextmanager
def served(probe_dir):
    server, _ = serve(ViewerSite.open(probe_dir), extra_routes=CHECK_ROUTES)
    try:
        yield server.url
    finally:
        server.shutdown()
        server.server_close()


def directions(step=3.0):
    el, az = np.meshgrid(np.radians(np.arange(-87.0, 90.0, step)), np.radians(np.arange(0.0, 360.0, step)), indexing="ij")
    return np.stack([np.cos(el) * np.cos(az), np.sin(el), np.cos(el) * np.sin(az)], -1).reshape(-1, 3)


def sky(b, d, w, page="check"):
    """Sky lookups at level z(w) through ``window.check`` (three.js) or ``window.envcap`` (raw page)."""
    rows = [np.zeros_like(d).ravel().tolist(), d.ravel().tolist(), np.full(len(d), float(w)).tolist()]
    args = json.dumps(["sky", *rows] if page == "check" else ["sky", 0, *rows])
    api = "window.check" if page == "check" else "window.envcap"
    return np.array(b.evaluate(f"{api}.lookups(...JSON.parse({json.dumps(args)}))"), np.float64).reshape(-1, 3)


def close_to(got, ref, what):
    lit = ref > 0
    assert np.all(got[lit] > 0), f"{what}: {np.count_nonzero(got[lit] <= 0)} sky values black"
    rel = np.abs(got - ref)[lit] / ref[lit]
    assert rel.max() < HALF_ROUNDING, f"{what}: max relative difference {rel.max():.2e} from the normal path"
    return rel.max()


@pytest.fixture(scope="module")
def sun_sky_dir(gl_ctx, tmp_path_factory):
    """The canyon at 8^2 with the sun splatted into sky.ktx2 (peaks over the half-float range)."""
    from envcap.probeset.bake import bake_probe_set
    from envcap.scene import load_scene

    ps = bake_probe_set(load_scene("canyon"), resolution=8, spacing=100.0, ctx=gl_ctx, progress=False, sun_in_sky=True)
    return write_probe_set(tmp_path_factory.mktemp("sun_sky") / "canyon", ps, exr=False, previews=False,
                           writers=["ktx2", "webgl2"])


def test_three_sky_goes_rgba16f_and_matches_the_normal_path(chromium, viewer_probe_dir):
    ps = read_probe_set(viewer_probe_dir, distance=False)
    assert max(float(np.abs(lv).max()) for lv in ps.sky_levels) < HALF_MAX   # no sun in the map
    d, ws = directions(), (1e9, 16.0, 1.0)
    with served(viewer_probe_dir) as url:
        open_page(chromium, url + "three_check.html", "window.check.ready")
        assert chromium.evaluate("window.check.skyPlan")["format"] == "rgba32f"   # SwiftShader filters floats
        ref = {w: sky(chromium, d, w) for w in ws}
        with extension_hidden(chromium):
            open_page(chromium, url + "three_check.html", "window.check.ready")
            plan = chromium.evaluate("window.check.skyPlan")
            assert plan["format"] == "rgba16f" and plan["linear"], plan
            worst = max(close_to(sky(chromium, d, w), ref[w], f"three.js w={w:g}") for w in ws)
            assert chromium.errors == []
            # control: told that floats filter, three.js uploads RGBA32F LINEAR: incomplete, reads 0
            control = chromium.evaluate("window.check.reload({claimFloatLinear: true})")
            assert control["format"] == "rgba32f" and control["linear"]
            assert np.abs(sky(chromium, d, 16.0)).max() == 0.0, "the extension was not really hidden"
    print(f"three.js without OES_texture_float_linear: RGBA16F sky within {worst:.1e} of the normal path; "
          "RGBA32F linear there: black")


def test_raw_page_sky_goes_rgba16f(browser, chromium, viewer_server):
    d = directions(6.0)
    ref = sky(browser, d, 16.0, "envcap")   # the session's viewer page, extension on
    with extension_hidden(chromium):
        open_page(chromium, viewer_server.url)
        assert "sky RGBA16F" in chromium.evaluate("document.getElementById('status').textContent")
        close_to(sky(chromium, d, 16.0, "envcap"), ref, "raw WebGL2 page")
        assert chromium.errors == []


def screenshot(b):
    data = base64.b64decode(b.send("Page.captureScreenshot", format="png")["data"])
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), np.int32)


@pytest.mark.parametrize("page", ["three.html", pytest.param("babylon.html", marks=pytest.mark.slow)])  # ~10 s
def test_example_page_sky_pixels_match(chromium, viewer_server, page):
    if page == "babylon.html" and find_babylon() is None:
        pytest.skip("no Babylon.js build installed (.ci/run installs it: envcap.viewer.babylon_build.INSTALL_COMMAND)")
    open_page(chromium, viewer_server.url + page, "window.example.ready")
    assert chromium.evaluate("window.example.view().skyPlan.format") == "rgba32f"
    normal = screenshot(chromium)
    with extension_hidden(chromium):
        open_page(chromium, viewer_server.url + page, "window.example.ready")
        assert chromium.evaluate("window.example.view().skyPlan.format") == "rgba16f"
        hidden = screenshot(chromium)
        assert chromium.errors == []
    top = slice(0, normal.shape[0] // 4)   # above the facades' tops: the sky, looking along the street
    assert normal[top].mean() > 60 and hidden[top].mean() > 60, "black sky"
    view = slice(0, normal.shape[0] - 30)  # the caption names the format: left out
    diff = np.abs(normal[view] - hidden[view])
    assert diff.max() <= 2, f"example page: pixels differ by up to {diff.max()} levels without the extension"


def test_sun_in_the_map_falls_back_to_nearest_with_a_warning(chromium, sun_sky_dir):
    ps = read_probe_set(sun_sky_dir, distance=False)
    peak = float(ps.sky_levels[0][..., :3].max())
    assert peak > HALF_MAX   # precondition: this sky does not fit half floats
    sun = np.array(ps.manifest.sky.sun.direction)
    d = directions(2.0)
    with served(sun_sky_dir) as url, extension_hidden(chromium):
        open_page(chromium, url + "three_check.html", "window.check.ready")
        plan = chromium.evaluate("window.check.skyPlan")
        assert plan["format"] == "rgba32f" and not plan["linear"], plan
        assert any(level == "warning" and "NEAREST" in text for level, text in chromium.console), chromium.console
        level0 = sky(chromium, d, 1e9)
        up = d[:, 1] > 0.05
        assert np.all(level0[up].sum(axis=1) > 0), "black sky"
        assert level0.max() > HALF_MAX, f"the sun's energy was clamped: peak {level0.max():.4g}"
        angle = np.degrees(np.arccos(np.clip(d[np.argmax(level0.sum(axis=1))] @ sun, -1, 1)))
        assert angle < 1.5 * 90.0 / ps.manifest.resolution, f"sky peak {angle:.1f} deg from the manifest sun"
        open_page(chromium, url)   # the raw page: the same choice, said in its status line
        assert "sky RGBA32F nearest" in chromium.evaluate("document.getElementById('status').textContent")
        assert chromium.errors == []
