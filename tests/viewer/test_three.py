"""three.js (r187, shipped in envcap/viewer/web/three/ for the example page and web exports)
loads a probe set with ``envcap/viewer/web/three_probes.js`` in headless Chromium: the sky and a
probe agree in orientation with the manifest's sun, and the runtime chunk in a RawShaderMaterial
gives the numpy twin's lookups."""

import json
from pathlib import Path

import numpy as np
import pytest
from viewer_pages import open_page

from envcap.probeset.store import read_probe_set
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet
from envcap.viewer import WEB_DIR, ViewerSite, serve

HERE = Path(__file__).resolve().parent
THREE = WEB_DIR / "three"   # three.js r187 build files (MIT), shipped with the viewer


@pytest.fixture(scope="module")
def three_page(chromium, viewer_probe_dir):
    if not (THREE / "three.module.js").is_file():
        pytest.fail("three.js build files missing from envcap/viewer/web/three")

    routes = {"/three_check.html": HERE / "three_check.html", "/three_check.js": HERE / "three_check.js"}
    server, thread = serve(ViewerSite.open(viewer_probe_dir), extra_routes=routes)
    try:
        yield open_page(chromium, server.url + "three_check.html", "window.check.ready")
    finally:
        server.shutdown()
        server.server_close()


def lookups(b, kind, x, d, w):
    args = json.dumps([kind, np.ravel(x).tolist(), np.ravel(d).tolist(), np.ravel(w).tolist()])
    return np.array(b.evaluate(f"window.check.lookups(...JSON.parse({json.dumps(args)}))"), np.float64).reshape(-1, 3)


def test_three_sky_and_probe_oriented_as_the_manifest_sun(three_page, viewer_probe_dir):
    ps = read_probe_set(viewer_probe_dir, distance=False)
    sun = np.array(ps.manifest.sky.sun.direction)
    el, az = np.meshgrid(np.radians(np.arange(-87.0, 90.0, 2.0)), np.radians(np.arange(0.0, 360.0, 2.0)), indexing="ij")
    d = np.stack([np.cos(el) * np.cos(az), np.sin(el), np.cos(el) * np.sin(az)], -1).reshape(-1, 3)
    sky = lookups(three_page, "sky", np.zeros_like(d), d, np.full(len(d), 1e9)).sum(axis=1)
    angle = np.degrees(np.arccos(np.clip(d[np.argmax(sky)] @ sun, -1, 1)))
    assert angle < 1.5 * 90.0 / ps.manifest.resolution, f"three.js sky peak {angle:.1f} deg from the manifest sun"
    p = np.array(ps.manifest.streets[0].probes[2].position)
    toward = np.array([[0.0, 0.4, 1.0], [0.0, 0.4, -1.0]]) / np.hypot(0.4, 1.0)
    lum = lookups(three_page, "nearest", np.stack([p, p]), toward, [14.0, 14.0]).sum(axis=1)
    lit = 0 if -sun[2] > 0 else 1
    assert lum[lit] > 1.5 * lum[1 - lit], f"lit facade {lum[lit]:.4g} vs shadowed {lum[1 - lit]:.4g}"
    print(f"three.js: sky peak {angle:.2f} deg from the sun; lit / shadowed facade {lum[lit] / lum[1 - lit]:.2f}")
    assert three_page.errors == []


def test_three_runtime_chunk_matches_numpy_twin(three_page, viewer_probe_dir):
    ps = read_probe_set(viewer_probe_dir, distance=False)
    st = ps.manifest.streets[0]
    rng = np.random.default_rng(31)
    n = 600
    x = np.float32(np.c_[rng.uniform(-300, 300, n), rng.uniform(0.2, 12, n), rng.uniform(-7.5, 7.5, n)]).astype(np.float64)
    d = rng.normal(size=(n, 3))
    d = np.float32(d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float64)
    w = np.float32(np.exp(rng.uniform(0, np.log(1e5), n))).astype(np.float64)
    got = lookups(three_page, "planes_mip", x, d, w)
    ref = sample_street(ProbeChains(ps.levels, ps.manifest.lobes.powers), ps.sky_levels,
                        RuntimeStreet.from_manifest(st), x, d, w, "planes_mip")
    err = np.abs(got - ref).max() / np.abs(ref).max()
    assert err < 1e-4, f"three.js planes_mip: max error {err:.2e} of the largest value"
