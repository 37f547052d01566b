"""An engine developer's path to the web, typed as a user types it: bake a probe set (without the
WebGL2 atlas), ``envcap export web`` it, serve the site with ``python3 -m http.server`` (no envcap
process) and open each engine's example page (three.js, Babylon.js) in a browser.  The page's
pixels are checked against the numpy twin: the background (the street as the probes see it from
the camera, the sky above) pixel for pixel through the page's tone map, a mirrored lookup is far
off (orientation), the sky is not black, and the diffuse spheres have the runtime's colors."""

import base64
import io
import json

import numpy as np
import pytest
from PIL import Image

from envcap.probeset.store import read_probe_set
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet
from envcap.viewer.babylon_build import find_babylon

pytestmark = pytest.mark.slow   # a bake, an export, a server and a page: ~15 s on 2 idle cores
CAPTION_ROWS = 30               # the page's caption sits over the bottom rows


def tonemap(L, exposure):
    c = L * exposure
    return 255.0 * (c / (1.0 + c)) ** (1.0 / 2.2)


def pixel_rays(view, cols, rows):
    """World ray directions of screenshot pixels (column, row from the top), as the page's shader."""
    w, h = view["width"], view["height"]
    fx, fy = (np.asarray(cols) + 0.5) / w * 2 - 1, (h - 1 - np.asarray(rows) + 0.5) / h * 2 - 1
    fx = fx * w / h
    r = np.array(view["rot"], np.float64).reshape(3, 3).T   # columns: right, up, back
    d = np.stack([fx * view["tanHalfFov"], fy * view["tanHalfFov"], -np.ones_like(fx)], -1) @ r.T
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def sphere_hits(view, d):
    """Per ray: the sphere hit first (index) or -1, and the hit point (world)."""
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


PAGES = {"three": "three.js r187", "babylon": "Babylon.js 9."}
"""Each engine's example page and what its caption names."""


@pytest.mark.parametrize("engine", sorted(PAGES))
def test_bake_export_serve_engine_page(terminal, chromium, engine):
    if engine == "babylon" and find_babylon() is None:
        pytest.skip("no Babylon.js build installed (.ci/run installs it: envcap.viewer.babylon_build.INSTALL_COMMAND)")
    terminal.run("envcap capture canyon --out probes --resolution 8 --spacing 100 --quiet")
    assert not (terminal.cwd / "probes" / "probes_atlas.ktx2").exists()   # the export makes it
    out = terminal.run("envcap export web probes --out site").stdout
    assert "python3 -m http.server" in out
    server = terminal.start("python3 -m http.server 0 --bind 127.0.0.1 --directory site")
    try:
        line = server.stdout.readline()
        assert "port" in line, line
        url = f"http://127.0.0.1:{int(line.split('port ')[1].split()[0])}/"
        chromium.errors.clear()
        chromium.goto(url + f"{engine}.html")
        assert chromium.evaluate("window.example.ready.then(() => 'ok', e => 'error: ' + e.message)") == "ok", \
            chromium.errors
        assert chromium.errors == []
        view = chromium.evaluate("window.example.view()")
        png = base64.b64decode(chromium.send("Page.captureScreenshot", format="png")["data"])
        shot = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), np.float64)
        caption = chromium.evaluate("document.getElementById('caption').textContent")
    finally:
        server.terminate()
        server.wait(10)
        chromium.goto("about:blank")
    assert shot.shape[:2] == (view["height"], view["width"]), (shot.shape, view)
    assert PAGES[engine] in caption and "sky RGBA32F" in caption, caption

    ps = read_probe_set(terminal.cwd / "probes", distance=False)
    street = ps.manifest.streets[0]
    chains = ProbeChains(ps.levels, ps.manifest.lobes.powers)
    runtime = RuntimeStreet.from_manifest(street)
    assert view["street"] == street.name

    def lookup(x, d, w):
        return sample_street(chains, ps.sky_levels, runtime, np.float32(x).astype(np.float64),
                             np.float32(d).astype(np.float64), np.full(len(d), float(w)), "planes_mip")

    # the background, pixel for pixel: a grid over the page away from the spheres and the caption
    rows, cols = np.meshgrid(np.arange(4, view["height"] - CAPTION_ROWS, 17), np.arange(4, view["width"], 23),
                             indexing="ij")
    rows, cols = rows.ravel(), cols.ravel()
    d = pixel_rays(view, cols, rows)
    hit, _ = sphere_hits(view, d)
    free = hit < 0
    rows, cols, d = rows[free], cols[free], d[free]
    x = np.broadcast_to(np.array(view["position"]), d.shape)
    got = shot[rows, cols]
    ref = tonemap(lookup(x, d, view["power"]), view["exposure"])
    err = np.abs(got - ref)
    assert err.max() <= 2.0, f"background: {np.count_nonzero(err > 2)} of {err.size} channels off, max {err.max():.1f} levels"
    # orientation: the probes and the sky mirrored in x (what three.js's envMap path does) or in z are far off
    report = {"background_pixels": int(free.sum()), "max_error_levels": round(float(err.max()), 2)}
    for axis in (0, 2):
        m = d.copy()
        m[:, axis] *= -1
        mirrored = np.abs(got - tonemap(lookup(x, m, view["power"]), view["exposure"])).mean()
        assert mirrored > 5 * max(err.mean(), 0.2), f"a lookup mirrored in {'xz'[axis // 2]} fits too: {mirrored:.2f} levels"
        report[f"mirrored_{'xz'[axis // 2]}_mean_levels"] = round(float(mirrored), 2)
    # the sky: looking up between the facades, not black, and sky where the twin says sky
    top = (rows < view["height"] // 6) & (d[:, 1] > 0.3)
    assert np.count_nonzero(top) > 10 and got[top].mean() > 60, "black sky"
    # the spheres: the diffuse ones (white, red) shaded with the runtime's E_1(n) at their surface
    for k, s in enumerate(view["spheres"]):
        c = np.array(s["center"])
        v = c - np.array(view["position"])
        r = np.array(view["rot"]).reshape(3, 3)   # rows: right, up, back
        e = r @ v                                  # eye space
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
            report[s["name"]] = round(float(np.abs(shot[pr, pc] - want).max()), 2)
    print(engine, json.dumps(report))
