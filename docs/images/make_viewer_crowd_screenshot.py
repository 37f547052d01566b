"""docs/images/viewer_crowd.png: the viewer page (``envcap view``) in headless Chromium with the
crowd on: 32 walkers of ``envcap crowd`` (the bundled walker, seed 0, frame 0 of the clip) on the
canyon baked at 32^2 with ``--webgl2 --scene-gltf`` (probes every 20 m), lit by the crowd GLSL with
every term (probes + self + neighbours + the sun), method fitted_planes_oblique; below it, one
walker close up with each term switch (probes only, + self, + neighbours), cropped from the view
(``viewer_crowd_terms.png``).

Run: ``PYTHONPATH=. python3 docs/images/make_viewer_crowd_screenshot.py`` (needs chromium and
websocket-client; ~1-2 min on 2 cores)."""

import tempfile
from pathlib import Path

from PIL import Image

from envcap.formats.scene_gltf_writer import registered_scene_writer
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.store import write_probe_set
from envcap.scene import load_scene
from envcap.viewer import ViewerSite, serve
from envcap.viewer.browser import Chromium

OUT = Path(__file__).resolve().parent / "viewer_crowd.png"
TERMS_OUT = Path(__file__).resolve().parent / "viewer_crowd_terms.png"
CROP = (9, 175, 209, 335)
"""The near walkers on the left of the view (page pixels), shown at twice the size per term."""

SETUP = """(async () => {
  const v = window.envcap.viewer, st = v.cfg.streets[0], mid = 0.5 * (st.start + st.end);
  document.getElementById('crowd').checked = true;
  document.getElementById('crowd_count').value = '32';
  document.getElementById('probes').checked = false; v.showProbes = false;
  v.method = v.methods.find((m) => m.name === 'fitted_planes_oblique');
  document.getElementById('method').value = v.method.name;
  const c = await v.crowdLoad(); await c.setCount(32); c.on = true; c.terms = 2; c.setTime(0);
  v.group = v.group.map(() => [mid, -500, 0, 0.1]);
  v.cam.pos = [mid - 13, 1.8, -1.0]; v.cam.yaw = 0.0; v.cam.pitch = -0.06;
  v.render(); return true; })()"""

CLOSE = """(() => {{ const v = window.envcap.viewer, c = v.crowd; c.terms = {terms};
  document.getElementById('crowd_terms').value = '{terms}'; v.render(); return true; }})()"""

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
            b.evaluate(SETUP)
            assert not b.errors, b.errors
            b.screenshot(OUT)
            crops = []
            for terms in (0, 1, 2):
                b.evaluate(CLOSE.format(terms=terms))
                shot = Path(tmp) / f"terms_{terms}.png"
                b.screenshot(shot)
                crops.append(Image.open(shot).convert("RGB"))
            assert not b.errors, b.errors
    finally:
        server.shutdown()
    w, h = CROP[2] - CROP[0], CROP[3] - CROP[1]
    strip = Image.new("RGB", (3 * 2 * w + 2 * 8, 2 * h), (255, 255, 255))
    for i, im in enumerate(crops):
        strip.paste(im.crop(CROP).resize((2 * w, 2 * h), Image.NEAREST), (i * (2 * w + 8), 0))
    strip.save(TERMS_OUT)
print(f"wrote {OUT} and {TERMS_OUT}")
