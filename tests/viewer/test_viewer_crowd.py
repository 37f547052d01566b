"""The crowd in the viewer's street view: the server's clip is ``envcap crowd``'s walkers (placed
and posed by envcap.crowd), the page draws them in headless Chromium with shaders/crowd for
WebGL2 (they appear where the walkers project, and only there), each term switch moves the
avatars' pixels the expected way, the page's linear crowd matches the moderngl ``envcap crowd``
renderer's (same instance data, same view-projection) and equals the numpy twin at its own
fragments."""

import json
import subprocess
import sys

import numpy as np
import pytest

from envcap.crowd.camera import Camera
from envcap.crowd.inputs import ALBEDO, default_avatar, material, read_probes
from envcap.crowd.instances import AvatarCycle, instance_texture, pose_crowd
from envcap.crowd.renderer import CrowdRenderer
from envcap.crowd.sphere_buffer import NEIGHBOURS, nearest_neighbours, neighbour_texture
from envcap.crowd.twin import CrowdTwin
from envcap.crowd.walkers import place_walkers
from envcap.runtime import methods
from envcap.runtime.street import StreetProbes
from envcap.viewer.crowd_site import FPS, FRAMES

W, H = 96, 64           # the linear target (small: SwiftShader shades every walker pixel in software)
COUNT, FRAME = 16, 3


@pytest.fixture(scope="module")
def crowd_ref(viewer_server, viewer_probe_dir):
    """What envcap.crowd makes of the viewer's set (an independent run of its functions): the
    description the page got, the walkers, the gait, the pose at FRAME."""
    desc = json.loads(viewer_server.body("/api/crowd.json"))
    ps = read_probes(viewer_probe_dir)
    street = StreetProbes.from_manifest(ps.manifest.streets[0])
    walkers = place_walkers(street, COUNT, desc["seed"])
    avatar = default_avatar()
    cycle = AvatarCycle.of(avatar.avatar, avatar.spheres)
    pose = pose_crowd(walkers, cycle, FRAME / FPS, np.array(desc["origin"]))
    return {"desc": desc, "ps": ps, "walkers": walkers, "avatar": avatar, "pose": pose}


@pytest.fixture(scope="module")
def crowd_page(chromium, viewer_server, crowd_ref):
    from viewer_pages import open_page

    if chromium.evaluate("location.href") != viewer_server.url:
        open_page(chromium, viewer_server.url)
    chromium.evaluate(f"window.envcap.crowd().then(c => c.setCount({COUNT})).then(() => true)")
    chromium.evaluate(f"(() => {{ window.envcap.viewer.crowd.frame = {FRAME}; return true; }})()")
    return chromium


def close_camera(pose, origin, aspect=W / H):
    """A camera 3 m from the walker nearest the crowd's middle, looking at its hips."""
    hips = pose.feet - origin + [0.0, 1.0, 0.0]
    k = int(np.argmin(np.abs(hips - hips.mean(axis=0)).sum(axis=1)))
    return Camera(hips[k] + [2.0, 0.8, 2.0], hips[k], aspect)


def page_linear(b, cam, terms=2, method="fitted_planes_oblique", output=0):
    """The page's crowd alone (linear RGBA, row 0 at the top) from ``cam`` with ``terms``
    (``output`` -1: the shading points, -2: the normals)."""
    vp = cam.view_proj().T.reshape(-1).tolist()   # column-major
    js = f"""(() => {{ const v = window.envcap.viewer, c = v.crowd, a = {json.dumps([vp, cam.eye.tolist(), terms, method])};
      c.terms = a[2]; c.on = true;
      const px = c.renderLinear({{viewProj: a[0], eye: a[1]}}, v.cfg.streets[c.desc.street], v.tex, {{name: a[3]}}, {W}, {H}, {output});
      return Array.from(px); }})()"""
    return np.array(b.evaluate(js), np.float32).reshape(H, W, 4)[::-1]


def test_the_crowd_routes_serve_envcap_crowds_walkers(viewer_server, crowd_ref):
    d, pose = crowd_ref["desc"], crowd_ref["pose"]
    j = d["joints"]
    assert j == crowd_ref["avatar"].avatar.joint_count
    clip = np.frombuffer(viewer_server.body(f"/api/crowd/walkers_{COUNT}.bin"), "<f4")
    per = COUNT * (6 * j + 2 * NEIGHBOURS) * 4
    assert clip.size == FRAMES * per
    block = clip[FRAME * per:(FRAME + 1) * per]
    inst = instance_texture(pose).reshape(-1)
    np.testing.assert_array_equal(block[:inst.size], inst)
    np.testing.assert_array_equal(block[inst.size:], neighbour_texture(pose, nearest_neighbours(pose.one)).reshape(-1))
    mesh = viewer_server.body("/api/crowd/avatar.bin")
    a = crowd_ref["avatar"].avatar
    assert len(mesh) == 4 * (22 * len(a.positions) + 3 * len(a.triangles))
    vertices = np.frombuffer(mesh, "<f4", 22 * len(a.positions)).reshape(-1, 22)
    np.testing.assert_array_equal(vertices[:, :3], a.positions.astype(np.float32))
    np.testing.assert_array_equal(vertices[:, 6:10], a.joints.astype(np.float32))
    np.testing.assert_array_equal(np.frombuffer(mesh, "<u4", offset=4 * vertices.size).reshape(-1, 3), a.triangles)
    for bad in ("/api/crowd/walkers_7.bin", "/api/crowd/../config.json", "/api/crowd/", "/api/crowd/walkers_16.bin/x"):
        assert viewer_server.body(bad) is None, bad
    cfg = json.loads(viewer_server.body("/api/config.json"))
    assert cfg["crowd"]["url"] == "api/crowd.json" and COUNT in cfg["crowd"]["counts"]


@pytest.mark.slow
def test_the_crowd_appears_in_the_street_view_where_walkers_project(crowd_page, crowd_ref):
    """The street view (the page's own camera, spheres and probes out of the way) with the crowd
    on and off: pixels change at the walkers' projected hips and stay at the sky above them."""
    pose, origin = crowd_ref["pose"], np.array(crowd_ref["desc"]["origin"])
    hips = pose.feet + [0.0, 1.0, 0.0]
    mid = hips.mean(axis=0)
    js = f"""(() => {{ const v = window.envcap.viewer, gl = v.gl, c = v.crowd, a = {json.dumps(mid.tolist())};
      gl.canvas.width = 160; gl.canvas.height = 100; v.showProbes = false;
      v.group = v.group.map(() => [a[0], -500, a[2], 0.1]);
      v.cam.pos = [a[0] - 14, 3.0, a[2] + 0.5]; v.cam.yaw = 0.0; v.cam.pitch = -0.12; c.terms = 2;
      const f = v.forward(), r = [-f[2], 0, f[0]].map(x => x / Math.hypot(f[0], f[2])), u = [r[1]*f[2]-r[2]*f[1], r[2]*f[0]-r[0]*f[2], r[0]*f[1]-r[1]*f[0]];
      const view = c.camera(v.cam.pos, [...r, ...u, -f[0], -f[1], -f[2]], Math.tan(0.5 * 70 * Math.PI / 180), 160 / 100);
      const shot = (on) => {{ c.on = on; v.render(); const p = new Uint8Array(160 * 100 * 4); gl.readPixels(0, 0, 160, 100, gl.RGBA, gl.UNSIGNED_BYTE, p); return Array.from(p); }};
      return [Array.from(view.viewProj), shot(true), shot(false)]; }})()"""
    vp, on, off = crowd_page.evaluate(js)
    on = np.array(on).reshape(100, 160, 4)[::-1, :, :3].astype(int)
    off = np.array(off).reshape(100, 160, 4)[::-1, :, :3].astype(int)
    M = np.array(vp).reshape(4, 4).T
    clip = np.c_[hips - origin, np.ones(len(hips))] @ M.T
    front = clip[:, 3] > 0.5
    ndc = clip[:, :2] / clip[:, 3:]
    col, row = ((ndc[:, 0] + 1) / 2 * 160).astype(int), ((1 - (ndc[:, 1] + 1) / 2) * 100).astype(int)
    seen = front & (col >= 1) & (col < 159) & (row >= 1) & (row < 99)
    assert seen.sum() >= 4, "too few walkers in view to test"
    changed = [np.abs(on[r - 1:r + 2, c - 1:c + 2] - off[r - 1:r + 2, c - 1:c + 2]).sum(axis=2).max() > 6
               for r, c in zip(row[seen], col[seen])]
    assert np.mean(changed) >= 0.75, changed
    diff = np.abs(on - off).sum(axis=2) > 0
    assert diff[:15].sum() == 0, "the crowd changed pixels high in the sky"
    assert 0.002 < diff.mean() < 0.5, diff.mean()


@pytest.mark.slow
def test_each_term_switch_moves_the_avatars_pixels_the_expected_way(crowd_page, crowd_ref):
    cam = close_camera(crowd_ref["pose"], np.array(crowd_ref["desc"]["origin"]))
    imgs = [page_linear(crowd_page, cam, t) for t in (0, 1, 2)]
    on_map = np.array(crowd_page.evaluate("window.envcap.viewer.crowd.positions()"))   # the map's walker dots
    np.testing.assert_allclose(on_map, crowd_ref["pose"].heads[:, 0] + crowd_ref["desc"]["origin"], atol=1e-4)
    mask = (imgs[0][..., 3] > 0) & (imgs[1][..., 3] > 0) & (imgs[2][..., 3] > 0)
    assert mask.sum() > 200, mask.sum()
    lum = [(im[..., :3] @ [0.2126, 0.7152, 0.0722])[mask] for im in imgs]
    means = [float(x.mean()) for x in lum]
    print("mean luminance on avatar pixels: probes %.4g, + self %.4g, + neighbours %.4g" % tuple(means))
    assert np.isfinite(lum).all()
    assert means[1] < 0.99 * means[0], "its own bones must darken the avatar"
    assert np.mean(lum[1] <= lum[0] * (1 + 1e-4)) > 0.9, "most pixels darken with + self"
    assert np.mean(np.abs(lum[2] - lum[1]) > 1e-3 * lum[1]) > 0.02, "the neighbours changed no pixel"
    assert means[2] <= means[1] * (1 + 1e-3), "the neighbours must not brighten the crowd on average"


def same_surface(mask, points, step=0.10):
    """``mask`` pixels whose 3 x 3 neighbours are all in ``mask`` and on the same surface (shading
    points within ``step`` m): away from silhouettes and from an arm in front of the body."""
    out = mask.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            out &= np.roll(np.roll(mask, dy, 0), dx, 1)
            out &= np.linalg.norm(np.roll(np.roll(points, dy, 0), dx, 1) - points, axis=2) < step
    return out


def test_the_page_crowd_matches_the_moderngl_crowd_renderer(crowd_page, crowd_ref, gl_ctx):
    """The page's linear crowd (WebGL2 on SwiftShader) against envcap.crowd.renderer (GL 4.50 on
    llvmpipe), same instance data and view-projection: the same coverage and shading points, and
    the radiance on same-surface pixels within what the two rasterizers' sub-pixel vertex snapping
    explains (shading points ~1 mm and normals ~0.4 deg apart on this low-poly avatar: ~1 %
    on a glossy Lafortune lobe; docs/viewer.md, Crowd)."""
    ref, desc = crowd_ref, crowd_ref["desc"]
    m = methods.get(desc["default_method"])
    r = CrowdRenderer(gl_ctx, ref["ps"], ref["walkers"].street.runtime_street(m.planes), m, ref["avatar"], material(),
                      None, (W, H), COUNT, targets=True)
    try:
        np.testing.assert_allclose(r.origin, desc["origin"])
        cam = close_camera(ref["pose"], r.origin)
        want = r.render(ref["pose"], cam, "neighbours")
    finally:
        r.release()
    got = page_linear(crowd_page, cam, 2, m.name)
    points = page_linear(crowd_page, cam, 2, m.name, output=-1)
    inside = want["normal"][..., 3] == 1.0
    assert abs(np.mean(got[..., 3] > 0) - np.mean(inside)) < 0.01, "not the same coverage"
    inner = same_surface(inside & (got[..., 3] > 0), want["position"][..., :3])
    assert inner.sum() > 50, inner.sum()
    gap = np.linalg.norm(points[inner][:, :3] - want["position"][inner][:, :3], axis=1)
    assert np.all(points[inner][:, 3] - 1 == want["position"][inner][:, 3]), "not the same walkers"
    g, w = got[inner][:, :3].astype(np.float64), want["color"][inner].astype(np.float64)
    rel = np.abs(g - w).max(axis=1) / np.maximum(w.max(axis=1), 1e-6)
    print("page vs moderngl on %d same-surface pixels: shading points %.2g mm apart (median), radiance "
          "median %.2e, 90th %.2e, max %.2e" % (inner.sum(), 1e3 * np.median(gap), np.median(rel),
                                               np.quantile(rel, 0.9), rel.max()))
    assert np.median(gap) < 5e-3
    assert np.median(rel) < 5e-3
    assert np.quantile(rel, 0.9) < 2e-2
    assert rel.max() < 6e-2


@pytest.mark.slow
def test_the_page_crowd_equals_the_numpy_twin_at_its_own_fragments(crowd_page, crowd_ref):
    """At a dozen of the page's own fragments (its shading point, normal and self spheres read
    back), the page's radiance with the sun off equals envcap.crowd.twin: Eq. 3 through the
    runtime lookup (probes only) and Eq. 3 + bounced - blocked of its bones and neighbours."""
    ref, desc = crowd_ref, crowd_ref["desc"]
    m = methods.get(desc["default_method"])
    origin = np.array(desc["origin"])
    cam = close_camera(ref["pose"], origin)
    crowd_page.evaluate("(() => { const s = window.envcap.viewer.crowd.desc.sun; s.on = s.irradiance; s.irradiance = [0, 0, 0]; return 1; })()")
    try:
        probes, full = page_linear(crowd_page, cam, 0, m.name), page_linear(crowd_page, cam, 2, m.name)
        point, normal, s0, s1 = (page_linear(crowd_page, cam, 2, m.name, output=o) for o in (-1, -2, -3, -4))
    finally:
        crowd_page.evaluate("(() => { const s = window.envcap.viewer.crowd.desc.sun; s.irradiance = s.on; return 1; })()")
    rows, cols = np.nonzero(point[..., 3] > 0)
    pick = np.random.default_rng(1).choice(len(rows), size=12, replace=False)
    twin = CrowdTwin(ref["ps"], ref["walkers"].street.runtime_street(m.planes), m, material(), origin, ALBEDO)
    neighbours = nearest_neighbours(ref["pose"].one)
    got, want = [], []
    for y, x in zip(rows[pick], cols[pick]):
        t = twin.terms(point[y, x, :3], normal[y, x, :3], cam.eye, int(round(point[y, x, 3])) - 1,
                       np.stack([s0[y, x], s1[y, x]]), ref["pose"], neighbours)
        got.append(np.r_[probes[y, x, :3], full[y, x, :3]])
        want.append(np.r_[t.eq3, t.eq3 + t.all_term])
    got, want = np.array(got), np.array(want)
    err = np.abs(got - want) / np.abs(want[:, :3]).max(axis=1, keepdims=True)
    print("page vs numpy twin at 12 fragments: max %.2e (probes only), %.2e (+ neighbours)" % (err[:, :3].max(), err[:, 3:].max()))
    assert np.abs(want[:, 3:] - want[:, :3]).max() > 1e-3 * np.abs(want).max(), "the terms changed nothing here"
    assert err.max() < 1e-3   # float32 WebGL2 against float64 numpy, the same half-float probe texels: ~1e-5 measured


def test_view_refuses_a_file_that_is_no_avatar_in_one_line(viewer_probe_dir, tmp_path):
    bad = tmp_path / "not_an_avatar.glb"
    bad.write_bytes(b"glTF\x02\x00\x00\x00" + bytes(12))
    p = subprocess.run([sys.executable, "-m", "envcap", "view", str(viewer_probe_dir), "--avatar", str(bad)],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and p.stdout == ""
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("envcap: error: ") and "not_an_avatar.glb" in lines[0], p.stderr


@pytest.mark.slow
def test_the_crowd_switches_drive_the_crowd(crowd_page):
    """The page's controls: walkers on/off, terms, count (its clip fetched), walk (the clip's time
    runs while ticked and stops when unticked)."""
    js = """(async () => {
      const $ = (id) => document.getElementById(id), v = window.envcap.viewer, gl = v.gl;
      gl.canvas.width = 64; gl.canvas.height = 40;
      const set = async (id, value) => { const e = $(id); if (e.type === 'checkbox') e.checked = value; else e.value = value;
        e.onchange(); await new Promise((r) => setTimeout(r, 300)); };
      const out = {hidden: $('crowd_controls').hidden, counts: Array.from($('crowd_count').options).map((o) => Number(o.value))};
      await set('crowd', true); await set('crowd_terms', '1'); await set('crowd_count', '32');
      const c = v.crowd; out.on = c.on; out.terms = c.terms; out.count = c.count; out.clip = c.clips.get(32).length;
      const t0 = c.time; await set('crowd_walk', true); await new Promise((r) => setTimeout(r, 600));
      out.walked = c.time - t0; await set('crowd_walk', false); const t1 = c.time;
      await new Promise((r) => setTimeout(r, 400)); out.after = c.time - t1;
      await set('crowd', false); out.off = c.on;
      await set('crowd_terms', '2'); await set('crowd_count', '16'); c.on = true; c.setTime(0); c.frame = 3;
      return out; })()"""
    out = crowd_page.evaluate(js)
    j = crowd_page.evaluate("window.envcap.viewer.crowd.desc.joints")
    assert out["hidden"] is False and out["counts"] == [8, 16, 32, 64]
    assert out["on"] is True and out["terms"] == 1 and out["count"] == 32
    assert out["clip"] == FRAMES * 32 * (6 * j + 2 * NEIGHBOURS) * 4
    assert out["walked"] > 0.1, out
    assert out["after"] == 0.0, out
    assert out["off"] is False
    assert crowd_page.errors == []


def test_view_avatar_serves_an_envcap_avatar_file_as_the_bundled_walker(viewer_probe_dir, viewer_server, tmp_path):
    """``envcap avatar walker.glb`` then ``envcap view --avatar``: the crowd's avatar is that file,
    and its mesh, skin and blockers serve byte for byte as the bundled walker annotated in memory."""
    from envcap.cli import main
    from envcap.core.resources import city_scenes_dir
    from envcap.viewer import ViewerSite

    glb = tmp_path / "my_walker.glb"
    assert main(["avatar", str(city_scenes_dir() / "avatars/walker.glb"), "--out", str(glb), "--quiet"]) == 0
    routes = ViewerSite.open(viewer_probe_dir, avatar=glb).routes()
    assert json.loads(routes["/api/crowd.json"]())["avatar"]["name"] == "my_walker.glb"
    assert routes["/api/crowd/avatar.bin"]() == viewer_server.body("/api/crowd/avatar.bin")
