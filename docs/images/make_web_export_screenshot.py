"""docs/images/web_export_three.png and web_export_babylon.png: the three.js and Babylon.js example
pages of an ``envcap export web`` site,
served by ``python3 -m http.server`` (no envcap process), in headless Chromium: the canyon baked
at 32^2 (probes every 20 m, without ``--webgl2``: the export makes the face atlas), four spheres
shaded by the runtime GLSL (planes_mip) in three.js RawShaderMaterials / Babylon.js ShaderMaterials
over the street as the probes see it (Babylon.js from an npm install: docs/engines.md, section 7).

Run: ``PYTHONPATH=. python3 docs/images/make_web_export_screenshot.py`` (needs chromium and
websocket-client; ~1 min on 2 cores)."""

import subprocess
import sys
import tempfile
from pathlib import Path

from envcap.cli import main
from envcap.viewer.browser import Chromium

HERE = Path(__file__).resolve().parent

with tempfile.TemporaryDirectory() as tmp:
    probes, site = Path(tmp) / "probes", Path(tmp) / "site"
    assert main(["capture", "canyon", "--out", str(probes), "--resolution", "32", "--spacing", "20", "--quiet"]) == 0
    assert main(["export", "web", str(probes), "--out", str(site)]) == 0
    server = subprocess.Popen([sys.executable, "-m", "http.server", "0", "--bind", "127.0.0.1", "--directory", str(site)],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env={"PYTHONUNBUFFERED": "1"})
    try:
        port = int(server.stdout.readline().split("port ")[1].split()[0])
        with Chromium(1000, 560) as b:
            for engine in ("three", "babylon"):
                b.goto(f"http://127.0.0.1:{port}/{engine}.html")
                assert b.evaluate("window.example.ready.then(() => 'ok', e => e.message)") == "ok", b.errors
                assert not b.errors, b.errors
                b.screenshot(HERE / f"web_export_{engine}.png")
                print(f"wrote {HERE / f'web_export_{engine}.png'}")
    finally:
        server.terminate()
        server.wait(10)
