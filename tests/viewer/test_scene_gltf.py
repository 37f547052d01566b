"""The viewer with the bake's ``scene.glb``: the page loads it without console errors and
rasterizes it as the street geometry, composed by depth with the ray-traced crowd spheres (a
facade pixel changes and is not the sky's colour; a sphere in front of the facade stays; a
sphere behind it is hidden; a sky pixel is untouched)."""

import json
import math

import numpy as np
import pytest
from viewer_pages import open_page

from envcap.formats.scene_gltf_writer import registered_scene_writer
from envcap.probeset.store import write_probe_set
from envcap.scene import load_scene
from envcap.viewer import ViewerSite, serve

W, H, TAN_HALF_FOV = 160, 100, math.tan(math.radians(35.0))  # the canvas (made small: SwiftShader) and the page's field of view
CAM = [50.0, 2.0, 0.0]   # canyon street 'main' (axis x, facades at z = -8 and +8), between probes


def pixel_towards(elevation_deg: float) -> list[int]:
    """The canvas pixel (x, y from the bottom) straight ahead at ``elevation_deg`` (pitch 0)."""
    v = math.tan(math.radians(elevation_deg)) / TAN_HALF_FOV
    return [W // 2, int((v + 1.0) * 0.5 * H)]


@pytest.fixture(scope="module")
def scene_browser(chromium, canyon_probe_set, tmp_path_factory):
    """The session's Chromium on the viewer page of ``canyon_probe_set`` written with ``scene.glb``."""
    with registered_scene_writer(load_scene("canyon")) as names:
        d = write_probe_set(tmp_path_factory.mktemp("viewer_scene") / "canyon", canyon_probe_set, exr=False,
                            previews=False, writers=["ktx2", "webgl2", *names])
    assert (d / "scene.glb").is_file()
    server, thread = serve(ViewerSite.open(d))
    try:
        yield open_page(chromium, server.url)
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)


def render_pixels(browser, pitch: float, group: list[list[float]], pixels: list[list[int]], scene: bool) -> np.ndarray:
    """RGBA8 of ``pixels`` after one render from ``CAM`` facing +z (the facade at z = +8) at
    ``pitch`` radians, with crowd spheres ``group`` ([x, y, z, r] world m), scene.glb on or off."""
    js = f"""(() => {{
      const v = window.envcap.viewer, gl = v.gl, a = {json.dumps([CAM, pitch, group, pixels, scene])};
      v.cam.pos = a[0].slice(); v.cam.yaw = Math.PI / 2; v.cam.pitch = a[1];
      v.group = a[2]; v.showProbes = false; v.showScene = a[4]; gl.canvas.width = {W}; gl.canvas.height = {H};
      v.render();
      return a[3].map(([x, y]) => {{ const p = new Uint8Array(4); gl.readPixels(x, y, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, p); return Array.from(p); }});
    }})()"""
    return np.array(browser.evaluate(js), np.int64)


def test_scene_glb_loads_without_console_errors(scene_browser):
    assert scene_browser.errors == []
    status = scene_browser.evaluate("document.getElementById('status').textContent")
    assert "scene.glb" in status and "triangles" in status, status
    assert scene_browser.evaluate("window.envcap.viewer.scene.triangles") > 1000


def test_scene_geometry_drawn_and_composed_by_depth_with_spheres(scene_browser):
    facade = pixel_towards(20.0)                  # hits the z = +8 facade about 4.9 m up
    in_front = pixel_towards(math.degrees(math.atan2(-1.4, 7.0)))  # the center of a sphere at z = 7, y = 0.6
    behind = pixel_towards(math.degrees(math.atan2(2.0, 14.0)))    # towards a sphere at z = 14 behind the facade
    far_away = [CAM[0], -500.0, 0.0, 0.1]
    spheres = [[CAM[0], 0.6, 7.0, 0.6], [CAM[0], 4.0, 14.0, 1.0], far_away, far_away, far_away, far_away]
    pts = [facade, in_front, behind]
    on = render_pixels(scene_browser, 0.0, spheres, pts, True)
    off = render_pixels(scene_browser, 0.0, spheres, pts, False)
    on_hidden = render_pixels(scene_browser, 0.0, [spheres[0], far_away, *spheres[2:]], pts, True)
    sky_on = render_pixels(scene_browser, 1.5, spheres, [[W // 2, H // 2]], True)[0]
    sky_off = render_pixels(scene_browser, 1.5, spheres, [[W // 2, H // 2]], False)[0]
    print("facade on/off", on[0], off[0], "sphere", on[1], off[1], "behind", on[2], on_hidden[2], off[2], "sky", sky_on)
    assert np.abs(on[0, :3] - off[0, :3]).sum() > 12, "the facade pixel looks the same without scene.glb"
    assert np.abs(on[0, :3] - sky_on[:3]).sum() > 12, "the facade pixel has the sky's colour"
    assert np.array_equal(on[1], off[1]), "a sphere in front of the geometry must not change"
    assert np.array_equal(on[2], on_hidden[2]), "a sphere behind the facade must be hidden by it"
    assert np.abs(off[2, :3] - on[2, :3]).sum() > 12, "without the geometry the sphere behind the facade shows"
    assert np.array_equal(sky_on, sky_off), "the sky straight up must not change"
    assert scene_browser.errors == []
