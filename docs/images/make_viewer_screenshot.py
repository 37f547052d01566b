"""docs/images/viewer.png: the viewer page (``envcap view``) in headless Chromium on the canyon
baked at 32^2 with ``--webgl2 --scene-gltf`` (probes every 20 m; the street geometry is the bake's
``scene.glb``), method planes_mip, a glossy lobe power of 64.

Run: ``PYTHONPATH=. python3 docs/images/make_viewer_screenshot.py`` (needs chromium and
websocket-client; ~1 min on 2 cores)."""

import tempfile
from pathlib import Path

from envcap.formats.scene_gltf_writer import registered_scene_writer
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.store import write_probe_set
from envcap.scene import load_scene
from envcap.viewer import ViewerSite, serve
from envcap.viewer.browser import Chromium

OUT = Path(__file__).resolve().parent / "viewer.png"

with tempfile.TemporaryDirectory() as tmp:
    scene = load_scene("canyon")
    ps = bake_probe_set(scene, resolution=32, spacing=20.0, progress=False)
    with registered_scene_writer(scene) as scene_writer:
        d = write_probe_set(Path(tmp) / "canyon", ps, exr=False, previews=False, writers=["ktx2", "webgl2", *scene_writer])
    server, _ = serve(ViewerSite.open(d))
    try:
        with Chromium(1000, 560) as b:
            b.goto(server.url)
            b.evaluate("window.envcap.ready")
            b.evaluate("(() => { const v = window.envcap.viewer; v.cam.pos = [-37, 1.7, -2.5]; v.cam.yaw = 0.12;"
                       " v.cam.pitch = 0.02; v.placeGroup(); v.render(); return true; })()")
            assert not b.errors, b.errors
            b.screenshot(OUT)
    finally:
        server.shutdown()
print(f"wrote {OUT}")
