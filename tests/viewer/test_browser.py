"""The viewer page in a real browser (headless Chromium, WebGL2 on SwiftShader): it loads without
console errors, its WebGL2 runtime (the face-atlas probe layout, the runtime GLSL's WebGL2 target)
matches the numpy twin per method, and the probes and sky it loads are oriented as the manifest's
sun says."""

import json

import numpy as np
import pytest

from envcap.probeset.store import read_probe_set
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet
from envcap.viewer.site import viewer_methods

N_LOOKUPS = 1500
TOLERANCE = 1e-4
"""Browser vs numpy twin, absolute, as a fraction of the largest reference value (see docs/viewer.md:
the face atlas is RGBA16F like probes.ktx2, so the differences are filtering arithmetic)."""


def lookups(browser, method, x, d, w):
    """Run ``window.envcap.lookups`` (world points ``x``, unit ``d``, powers ``w``) on street 0; the
    arrays travel as one JSON string (a large JavaScript array literal compiles slowly)."""
    args = json.dumps([method, 0, x.ravel().tolist(), d.ravel().tolist(), w.tolist()])
    got = browser.evaluate(f"window.envcap.lookups(...JSON.parse({json.dumps(args)}))")
    return np.array(got, np.float64).reshape(-1, 3)


def f32(a):
    return np.asarray(a, np.float32).astype(np.float64)


def test_page_loads_without_console_errors(browser):
    assert browser.errors == []
    status = browser.evaluate("document.getElementById('status').textContent")
    assert "canyon" in status and "6 probes" in status and "RGBA32F" in status, status
    assert browser.evaluate("window.envcap.methods()")[:4] == ["nearest", "planes", "planes_mip", "blend"]


@pytest.fixture(scope="module")
def twin(viewer_probe_dir):
    ps = read_probe_set(viewer_probe_dir, distance=False)
    st = ps.manifest.streets[0]
    rng = np.random.default_rng(13)
    a = np.array([p.position[0] for p in st.probes])
    x = np.c_[rng.uniform(a.min() - 20, a.max() + 20, N_LOOKUPS), rng.uniform(0.2, 12, N_LOOKUPS), rng.uniform(-7.5, 7.5, N_LOOKUPS)]
    d = rng.normal(size=(N_LOOKUPS, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(0, np.log(1e5), N_LOOKUPS))
    return ps, st, f32(x), f32(d), f32(w)


@pytest.mark.parametrize("method", [m["name"] for m in viewer_methods()])
def test_webgl2_pixels_match_numpy_twin(browser, twin, method):
    """Each method the page offers, ``N_LOOKUPS`` lookups rendered to an RGBA32F target and read
    back, against ``envcap.runtime.sampling.sample_street`` on the cube-array probes."""
    ps, st, x, d, w = twin
    got = lookups(browser, method, x, d, w)
    planes = "fitted" if method == "fitted_planes_mip" else "nominal"
    ref = sample_street(ProbeChains(ps.levels, ps.manifest.lobes.powers), ps.sky_levels,
                        RuntimeStreet.from_manifest(st, planes), x, d, w, method)
    assert np.all(np.isfinite(got))
    err = np.abs(got - ref).max() / np.abs(ref).max()
    assert err < TOLERANCE, f"{method}: max |browser - numpy| = {err:.2e} of the largest value"
    print(f"{method}: max error {err:.2e} of max {np.abs(ref).max():.4g}")


def test_sky_and_probe_oriented_as_the_manifest_sun(browser, twin):
    """The sky's brightest direction (level 0, the circumsolar peak) lies at the manifest's sun;
    from a probe, the facade the sun lights (normal . sun > 0) is brighter than the shadowed one."""
    ps, st, *_ = twin
    sun = np.array(ps.manifest.sky.sun.direction)
    el, az = np.meshgrid(np.radians(np.arange(-87.0, 90.0, 2.0)), np.radians(np.arange(0.0, 360.0, 2.0)), indexing="ij")
    d = np.stack([np.cos(el) * np.cos(az), np.sin(el), np.cos(el) * np.sin(az)], -1).reshape(-1, 3)
    sky = lookups(browser, "sky", np.zeros_like(d), d, np.full(len(d), 1e9)).sum(axis=1)
    peak = d[np.argmax(sky)]
    angle = np.degrees(np.arccos(np.clip(peak @ sun, -1, 1)))
    texel = 90.0 / ps.manifest.resolution
    assert angle < 1.5 * texel, f"sky peak {peak} is {angle:.1f} deg from the manifest sun {sun}"
    # the probe: facades at z = +-8 (normals -+z); the sun's z component picks the lit one
    p = np.array(st.probes[2].position)
    toward = np.array([[0.0, 0.4, 1.0], [0.0, 0.4, -1.0]])
    toward /= np.linalg.norm(toward, axis=1, keepdims=True)
    lum = lookups(browser, "nearest", np.stack([p, p]), toward, np.array([14.0, 14.0])).sum(axis=1)
    lit = 0 if -sun[2] > 0 else 1  # facade seen toward +z has normal -z
    assert lum[lit] > 1.5 * lum[1 - lit], f"lit facade {lum[lit]:.4g} vs shadowed {lum[1 - lit]:.4g}"
    print(f"sky peak {angle:.2f} deg from the sun (texel {texel:.1f} deg); lit / shadowed facade {lum[lit] / lum[1 - lit]:.2f}")


def test_screenshot_of_the_street_view(browser, tmp_path):
    """The view renders an image with content (not a blank or error canvas)."""
    browser.evaluate("window.envcap.viewer.render()")
    stats = browser.evaluate("(() => { const c = document.getElementById('view'), g = c.getContext('webgl2');"
                             " const p = new Uint8Array(c.width * c.height * 4); g.readPixels(0, 0, c.width, c.height,"
                             " g.RGBA, g.UNSIGNED_BYTE, p); let s = 0, s2 = 0, n = 0;"
                             " for (let i = 1; i < p.length; i += 4) { s += p[i]; s2 += p[i] * p[i]; ++n; }"
                             " return [s / n, Math.sqrt(s2 / n - (s / n) ** 2)]; })()")
    mean, std = stats
    assert std > 5 and 10 < mean < 245, f"green channel mean {mean:.1f}, std {std:.1f}"
    assert browser.screenshot(tmp_path / "viewer.png").stat().st_size > 10_000
    assert browser.errors == []


def test_method_switch_changes_the_street_view(browser):
    """The view's spheres and background are shaded by the chosen method: ``nearest`` (no parallax)
    and ``planes_mip`` give different images from the same camera; the same method gives the same."""
    grab = ("((name) => { const v = window.envcap.viewer; v.method = v.methods.find((m) => m.name === name); v.render();"
            " const g = v.gl, c = g.canvas, p = new Uint8Array(c.width * c.height * 4);"
            " g.readPixels(0, 0, c.width, c.height, g.RGBA, g.UNSIGNED_BYTE, p); return btoa(String.fromCharCode(...p.subarray(0, 1 << 16)))"
            " + ':' + p.reduce((a, b) => a + b, 0); })")
    a, b, a2 = (browser.evaluate(f"{grab}({m!r})") for m in ("planes_mip", "nearest", "planes_mip"))
    browser.evaluate(f"{grab}('planes_mip')")
    assert a == a2 and a != b
    assert browser.errors == []
