"""The viewer on streets at any angle (issue 10) and on rung-ladder sets, in headless Chromium.

Framed street: the bundled canyon turned by ``YAW`` about +y and moved to ``ORIGIN_XZ`` (mesh,
normals, sun azimuth turned by hand here; the street keeps its numbers as frame coordinates),
baked like ``canyon_probe_set`` (8^2 faces, 6 probes), with ground slopes written into its
manifest.  The page's config carries the frame and slopes; its street-local points equal
``StreetUniforms.to_local`` and a hand-written rotation; its WebGL2 lookups equal the numpy
runtime (``sample_street``) at world points and world directions; and they equal the lookups of
the axis-aligned canyon (``canyon_probe_set``) at the points and directions turned back: the
frame handling checked against an independent bake, not against its own formulas.  The map draws
the street as a turned rectangle.

Rung ladder (``--ladder half_octave``): the page reads layer ``r = 0`` of each level (the chain of
the manifest's lobe table) and the sky array's layer 0; lookups equal ``sample_street`` on that
chain; an atlas holding every rung is refused with the reason."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from viewer_pages import open_page

from envcap.probeset.store import read_probe_set, write_probe_set
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet
from envcap.viewer import ViewerSite, serve

YAW = 30.0
ORIGIN_XZ = (2150.5, -1320.25)
SLOPES = (0.04, -0.03, 0.0, 0.05, -0.02, 0.01)   # written into the framed set's manifest, probe by probe
METHODS = ("nearest", "planes", "planes_mip", "blend")   # the page's own GLSL, the nearest and the blended runtime functions
TOLERANCE = 1e-4   # of the largest reference value, as tests/viewer/test_browser.py


def turn(yaw: float) -> np.ndarray:
    """Row-vector map of a plan turn by ``yaw`` (degrees, +x towards +z), written out by hand:
    (x, y, z) @ turn = (c x - s z, y, s x + c z)."""
    a = math.radians(yaw)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def frame_to_world(f):
    return np.asarray(f, np.float64) @ turn(YAW) + np.array([ORIGIN_XZ[0], 0.0, ORIGIN_XZ[1]])


def world_to_frame(p):
    return (np.asarray(p, np.float64) - np.array([ORIGIN_XZ[0], 0.0, ORIGIN_XZ[1]])) @ turn(YAW).T


def turned_canyon():
    """The canyon turned by ``YAW`` and moved to ``ORIGIN_XZ``: its street framed there."""
    from envcap.scene import load_scene

    sc = load_scene("canyon")
    T, m = turn(YAW), sc.mesh
    mesh = dataclasses.replace(m, positions=(m.positions.astype(np.float64) @ T).astype(np.float32),
                               normals=(m.normals.astype(np.float64) @ T).astype(np.float32),
                               origin=m.origin @ T + np.array([ORIGIN_XZ[0], 0.0, ORIGIN_XZ[1]]))
    p = sc.sky.params
    sky = dataclasses.replace(sc.sky, params=dataclasses.replace(p, sun_azimuth_deg=p.sun_azimuth_deg - YAW))
    return dataclasses.replace(sc, mesh=mesh, sky=sky, streets=[dataclasses.replace(st, yaw_deg=YAW, origin_xz=ORIGIN_XZ)
                                                                for st in sc.streets])


def with_slopes(ps):
    """``ps`` with ``SLOPES`` as its probes' nominal ground slopes (layer order)."""
    st = ps.manifest.streets[0]
    probes = tuple(dataclasses.replace(q, planes=dataclasses.replace(q.planes, ground_slope=SLOPES[q.layer]))
                   for q in st.probes)
    m = dataclasses.replace(ps.manifest, streets=[dataclasses.replace(st, probes=probes)])
    return dataclasses.replace(ps, manifest=m)


class Page:
    """The session's ``chromium`` on the viewer page of one probe-set directory (its own server)."""

    def __init__(self, browser, probe_dir):
        self.b, self.site = browser, ViewerSite.open(probe_dir)
        self.server, self.thread = serve(self.site)
        open_page(browser, self.server.url)

    def js(self, expression, *args):
        """``expression`` (a function of the arguments) called with ``args`` (sent as one JSON string)."""
        return self.b.evaluate(f"({expression})(...JSON.parse({json.dumps(json.dumps(args))}))")

    def lookups(self, method, x, d, w):
        got = self.js("(...a) => window.envcap.lookups(...a)", method, 0, x.ravel().tolist(), d.ravel().tolist(), w.tolist())
        return np.array(got, np.float64).reshape(-1, 3)

    def close(self):
        self.server.shutdown()
        self.server.server_close()
        self.thread.join(5)


@pytest.fixture(scope="module")
def framed_dir(gl_ctx, tmp_path_factory):
    """The turned canyon with slopes, baked (8^2 faces, 6 probes) and written with its atlas."""
    from envcap.probeset.bake import bake_probe_set

    ps = with_slopes(bake_probe_set(turned_canyon(), resolution=8, spacing=100.0, ctx=gl_ctx, progress=False))
    return write_probe_set(tmp_path_factory.mktemp("viewer_framed") / "canyon30", ps, exr=False, previews=False,
                           writers=["ktx2", "webgl2"])


@pytest.fixture(scope="module")
def framed(framed_dir, chromium):
    """(probe set read back, page) of the turned canyon with slopes."""
    page = Page(chromium, framed_dir)
    yield read_probe_set(framed_dir, distance=False), page
    page.close()


def test_long_framed_street_uploads_the_probes_nearest_its_middle(framed_dir):
    """A framed street of more than MAX_PROBES probes far from the world origin: the config's
    uniforms hold the MAX_PROBES probes nearest the street's middle along it (hand-picked here in
    frame coordinates), not those nearest some other point."""
    from envcap.runtime.limits import MAX_PROBES

    site = ViewerSite.open(framed_dir)
    st = site.manifest.streets[0]
    n = MAX_PROBES + 11
    s = np.linspace(-280.0, 300.0, n)            # along the frame; the street's middle is 0
    q0 = st.probes[0]
    probes = tuple(dataclasses.replace(q0, layer=i, position=tuple(frame_to_world([[v, 2.0, 0.0]])[0]))
                   for i, v in enumerate(s))
    m = dataclasses.replace(site.manifest, streets=[dataclasses.replace(st, probes=probes)])
    cfg = dataclasses.replace(site, manifest=m).streets()[0]
    u = cfg["uniforms"]["nominal"]
    want = np.sort(np.argsort(np.abs(s), kind="stable")[:MAX_PROBES])
    assert u["count"] == MAX_PROBES
    np.testing.assert_array_equal(np.array(u["pos"]).reshape(-1, 4)[:MAX_PROBES, 3], want)
    np.testing.assert_allclose(u["along_s"][:MAX_PROBES], s[want] - cfg["origin"][0], atol=1e-4)


def street_points(n, seed):
    """World points over the framed street and beyond its ends (0.2-12 m up), unit world directions, powers."""
    rng = np.random.default_rng(seed)
    f = np.c_[rng.uniform(-320, 320, n), rng.uniform(0.2, 12, n), rng.uniform(-7.5, 7.5, n)]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return frame_to_world(f), d, np.exp(rng.uniform(0, np.log(1e5), n))


def test_framed_config_points_and_map(framed):
    """The config's frame, corners, slopes and uniforms; the page's street-local points; the map."""
    ps, page = framed
    assert page.b.errors == []
    st = ps.manifest.streets[0]
    cfg = page.js("() => window.envcap.viewer.cfg")["streets"][0]
    a = math.radians(YAW)
    assert cfg["frame"] == {"yaw_deg": YAW, "origin_xz": list(ORIGIN_XZ), "cos_sin": [math.cos(a), math.sin(a)]}
    np.testing.assert_allclose(cfg["direction"], [math.cos(a), math.sin(a)], atol=1e-15)
    rect = np.array([[-300.0, 0, -8], [300, 0, -8], [300, 0, 8], [-300, 0, 8]])
    np.testing.assert_allclose(cfg["corners"], frame_to_world(rect)[:, [0, 2]], atol=1e-9)
    for ps_name in ("nominal", "fitted"):
        u = cfg["uniforms"][ps_name]
        np.testing.assert_array_equal(u["frame"], np.float32([math.cos(a), math.sin(a)]))
        planes = np.array(u["planes"]).reshape(-1, 4)[: u["count"]]
        probes = st.probes_along()
        np.testing.assert_array_equal(planes[:, 3], np.float32([SLOPES[q.layer] for q in probes]))
        if ps_name == "nominal":   # ground0 = ground - slope * (probe's along coordinate - origin's), hand-derived
            s = world_to_frame([q.position for q in probes])[:, 0] - cfg["origin"][0]
            ground = np.array([q.planes.ground for q in probes]) - cfg["origin"][1]
            np.testing.assert_allclose(planes[:, 2], ground - np.array([SLOPES[q.layer] for q in probes]) * s, atol=1e-4)
    # street-local points: StreetUniforms.to_local exactly, and the hand-written rotation within float32 rounding
    x, _, _ = street_points(200, 5)
    got = np.array(page.js("(xs) => window.envcap.viewer.toLocal(0, xs)", x.ravel().tolist())).reshape(-1, 3)
    uni = RuntimeStreet.from_manifest(st).uniforms(ps.manifest.lobes.powers)
    np.testing.assert_array_equal(np.float32(got), uni.to_local(x))
    np.testing.assert_allclose(got, world_to_frame(x) - uni.origin, atol=1e-4)
    # ... and with a street origin other than 0 (a street whose frame coordinates are kilometers out)
    o = [1000.0, 0.0, -1000.0]
    got = np.array(page.js("(xs, o) => { const st = window.envcap.viewer.cfg.streets[0], keep = st.origin; st.origin = o;"
                           " try { return window.envcap.viewer.toLocal(0, xs); } finally { st.origin = keep; } }",
                           x.ravel().tolist(), o)).reshape(-1, 3)
    np.testing.assert_array_equal(np.float32(got), RuntimeStreet.from_manifest(st).uniforms(ps.manifest.lobes.powers, o).to_local(x))
    # the map: the street's middle 200 m ahead along it is street-grey; the same distance along world +x is not
    mid = frame_to_world([[200.0, 0, 0]])[0]
    ax = np.array([ORIGIN_XZ[0] + 200.0, 0, ORIGIN_XZ[1]])
    px = page.js("(pts) => { const c = document.getElementById('map').getContext('2d');"
                 " return pts.map(([x, z]) => { const [u, v] = window.envcap.mapPoint(x, z);"
                 " return Array.from(c.getImageData(Math.round(u), Math.round(v), 1, 1).data); }); }",
                 [[mid[0], mid[2]], [ax[0], ax[2]]])
    assert px[0][:3] == [85, 85, 85] and px[1][:3] == [34, 34, 34], px


def test_framed_street_view_screenshot(framed, tmp_path):
    """The view of the framed street as loaded: camera along the street, spheres in front, content
    in the image (PNG kept for a look: ``ENVCAP_VIEWER_SHOT``)."""
    import os

    _, page = framed
    yaw = page.b.evaluate("window.envcap.viewer.cam.yaw")
    assert yaw == pytest.approx(math.radians(YAW))
    stats = page.b.evaluate("(() => { const c = document.getElementById('view'), g = c.getContext('webgl2');"
                            " const p = new Uint8Array(c.width * c.height * 4); g.readPixels(0, 0, c.width, c.height,"
                            " g.RGBA, g.UNSIGNED_BYTE, p); let s = 0, s2 = 0, n = 0;"
                            " for (let i = 1; i < p.length; i += 4) { s += p[i]; s2 += p[i] * p[i]; ++n; }"
                            " return [s / n, Math.sqrt(s2 / n - (s / n) ** 2)]; })()")
    assert stats[1] > 5 and 10 < stats[0] < 245, stats
    where = page.b.evaluate("document.getElementById('where').textContent")
    assert "30.0\u00b0" in where, where
    out = os.environ.get("ENVCAP_VIEWER_SHOT") or str(tmp_path / "framed.png")
    assert page.b.screenshot(out).stat().st_size > 5_000
    assert page.b.errors == []


@pytest.mark.parametrize("method", METHODS)
def test_framed_webgl2_lookups_match_numpy(framed, method):
    """World points and directions on the framed, sloped street: the page against ``sample_street``."""
    ps, page = framed
    x, d, w = street_points(400, 17)
    d, w = np.float32(d).astype(np.float64), np.float32(w).astype(np.float64)
    got = page.lookups(method, x, d, w)
    planes = "fitted" if method == "fitted_planes_mip" else "nominal"
    ref = sample_street(ProbeChains(ps.levels, ps.manifest.lobes.powers), ps.sky_levels,
                        RuntimeStreet.from_manifest(ps.manifest.streets[0], planes), x, d, w, method)
    assert np.all(np.isfinite(got))
    err = np.abs(got - ref).max() / np.abs(ref).max()
    assert err < TOLERANCE, f"{method}: max |browser - numpy| = {err:.2e} of the largest value"
    print(f"framed {YAW} deg {method}: max error {err:.2e}")


def test_framed_street_sees_the_axis_aligned_canyon(framed, canyon_probe_set):
    """Independent of the frame code's own formulas: the page's lookups on the turned canyon at
    turned points and directions equal numpy lookups of the axis-aligned canyon bake
    (``canyon_probe_set``) at the points and directions as they were (street surfaces: directions
    that meet a facade or the ground within the street; slopes 0 on both, ``nearest`` and
    ``planes_mip``)."""
    _, page = framed
    rng = np.random.default_rng(3)
    n = 300
    f = np.c_[rng.uniform(-250, 250, n), rng.uniform(0.5, 6, n), rng.uniform(-6, 6, n)]
    d = np.c_[rng.uniform(-1, 1, n), rng.uniform(-1, 0.3, n), rng.choice([-1.0, 1.0], n) * rng.uniform(0.5, 1, n)]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.exp(rng.uniform(0, np.log(64), n))
    ref_ps = canyon_probe_set
    # the page's street without the test's slopes (the canyon is flat): ground0 = the probe's ground, slope 0
    flat = page.js("() => { const s = window.envcap.viewer.cfg.streets[0], u = s.uniforms.nominal;"
                   " for (let i = 0; i < u.count; ++i) { u.planes[4 * i + 2] = s.probes[i].ground - s.origin[1];"
                   " u.planes[4 * i + 3] = 0; } return u.count; }")
    assert flat == 6
    chains = ProbeChains(ref_ps.levels, ref_ps.manifest.lobes.powers)
    for method in ("nearest", "planes_mip"):
        got = page.lookups(method, frame_to_world(f), d @ turn(YAW), w)
        ref = sample_street(chains, ref_ps.sky_levels, RuntimeStreet.from_manifest(ref_ps.manifest.streets[0]), f, d, w, method)
        rel = np.abs(got - ref).sum(axis=1) / np.abs(ref).sum(axis=1)
        print(f"{method}: turned vs axis-aligned bake: relative difference median {np.median(rel):.3f}, "
              f"p90 {np.quantile(rel, 0.9):.3f}, max {rel.max():.3f}")
        # measured: median 0.000, p90 0.003, max 0.015 (nearest and planes_mip): rasterizing the turned mesh
        assert np.median(rel) < 0.005 and np.quantile(rel, 0.9) < 0.02 and rel.max() < 0.1, method
    restored = page.js("() => fetch('/api/config.json').then((r) => r.json()).then((c) => {"
                       " window.envcap.viewer.cfg.streets = c.streets; return c.streets[0].uniforms.nominal.planes[3]; })")
    assert restored == np.float32(SLOPES[0])   # the config as served again


@pytest.fixture(scope="module")
def ladder_dir(gl_ctx, tmp_path_factory):
    from envcap.probeset.bake import bake_probe_set
    from envcap.scene import load_scene

    ps = bake_probe_set(load_scene("canyon"), resolution=16, spacing=300.0, ctx=gl_ctx, progress=False,
                        ladder_mode="half_octave")
    return write_probe_set(tmp_path_factory.mktemp("viewer_ladder") / "rungs", ps, exr=False, previews=False,
                           writers=["ktx2", "webgl2"])


def test_ladder_set_is_shown_through_its_first_rungs(ladder_dir, chromium):
    """A rung-ladder set: the page says what it shows, and its lookups are ``sample_street`` on
    layer r = 0 of each level (the manifest's chain) and the sky array's layer 0."""
    ps = read_probe_set(ladder_dir, distance=False)
    assert ps.manifest.ladder is not None and ps.manifest.ladder.per_level == 4
    page = Page(chromium, ladder_dir)
    try:
        status = page.b.evaluate("document.getElementById('status').textContent")
        assert "rung ladder half_octave" in status and "r = 0" in status, status
        rng = np.random.default_rng(8)
        n = 300
        x = np.float32(np.c_[rng.uniform(-200, 200, n), rng.uniform(0.2, 10, n), rng.uniform(-7, 7, n)]).astype(np.float64)
        d = rng.normal(size=(n, 3))
        d = np.float32(d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float64)
        w = np.float32(np.exp(rng.uniform(0, np.log(2e3), n))).astype(np.float64)
        chains = ProbeChains(ps.levels, ps.manifest.lobes.powers)   # layer r = 0 views, the manifest's powers
        for method in ("planes_mip",):
            got = page.lookups(method, x, d, w)
            ref = sample_street(chains, ps.sky_levels, RuntimeStreet.from_manifest(ps.manifest.streets[0]), x, d, w, method)
            err = np.abs(got - ref).max() / np.abs(ref).max()
            assert err < TOLERANCE, f"ladder {method}: {err:.2e}"
            print(f"ladder (r = 0 chain) {method}: max error {err:.2e}")
        assert page.b.errors == []
    finally:
        page.close()


def test_ladder_atlas_of_every_rung_is_refused(ladder_dir, tmp_path):
    """An atlas holding all R rungs per probe (not the one chain per probe the page reads) is an
    error naming the layer counts and the ladder."""
    import shutil

    from envcap.formats.face_atlas import face_atlas
    from envcap.formats.ktx2 import write_ktx2_array

    d = shutil.copytree(ladder_dir, tmp_path / "all_rungs")
    ps = read_probe_set(d, distance=False)
    write_ktx2_array(d / "probes_atlas.ktx2", face_atlas(ps.rungs, np.float16), fmt="rgba16f", premultiplied=True)
    with pytest.raises(ValueError, match=r"48 layers, the viewer needs 6 per probe = 12 \(a rung ladder of 4 rungs"):
        ViewerSite.open(d)
