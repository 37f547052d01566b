"""The pictures of docs/guide.md, made by the guide's own commands in a temporary directory:

* ``guide_view_demo.png``: ``envcap demo --out envcap-demo``, then ``envcap view envcap-demo``
  in headless Chromium (the street view, the controls and the map with the report's positions);
* ``guide_streets_map.png``: the map ``envcap streets`` writes for a copy of the generated
  city's files (``city-files/city.xml``; its margins cropped);
* ``guide_eval_error_vs_lobe.png``: ``envcap capture streets/scene.toml ...`` then ``envcap
  evaluate ... --positions 4``: the report's error-against-lobe-power plot;
* ``guide_view_streets.png``: ``envcap view probes --report eval`` on that probe set;
* ``guide_view_city.png``: the same scene baked as a city (``--workers 0``: the files a Dask
  cluster writes, bit for bit) and ``envcap view city``.

Every command runs this checkout's envcap (``python3 -m envcap`` with the checkout first on
``PYTHONPATH``), as the guide prints it.  Run: ``python3 docs/images/make_guide_images.py`` (needs
chromium and websocket-client; ~4 min on 2 cores, most of it the evaluation)."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image, ImageChops

REPO = Path(__file__).resolve().parents[2]
OUT = Path(__file__).resolve().parent
sys.path.insert(0, str(REPO))

from envcap.core.resources import city_scenes_dir  # noqa: E402
from envcap.viewer.browser import Chromium  # noqa: E402

ENV = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]),
           PYOPENGL_PLATFORM="egl", PYTHONUNBUFFERED="1")
CITY_FILES = city_scenes_dir() / "generated_city" / "data"
VIEW_BOX = (0, 0, 970, 530)
"""The part of a 1100 x 700 viewer page kept: the street view, the controls and the map."""


def argv(line: str) -> list[str]:
    words = shlex.split(line)
    return [sys.executable, "-m", "envcap", *words[1:]] if words[0] == "envcap" else words


def run(line: str, cwd: Path) -> None:
    print(f"$ {line}", flush=True)
    subprocess.run(argv(line), cwd=cwd, env=ENV, check=True, stdout=subprocess.DEVNULL)


def save(img: Image.Image, name: str) -> None:
    """Save ``img`` as docs/images/NAME, as a 256-colour palette PNG when the RGB one is over 200 KB."""
    path = OUT / name
    img = img.convert("RGB")
    img.save(path, optimize=True)
    if path.stat().st_size > 200_000:
        img.quantize(256, dither=Image.Dither.NONE).save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size // 1000} KB)", flush=True)


def view_screenshot(line: str, cwd: Path, name: str) -> None:
    """Start ``envcap view ...`` (port 0: a free one), load the page it prints in headless
    Chromium, wait for it to be ready, save the screenshot's :data:`VIEW_BOX`, stop the server."""
    print(f"$ {line}", flush=True)
    server = subprocess.Popen(argv(line), cwd=cwd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                              text=True, start_new_session=True)
    try:
        first = server.stdout.readline()
        if not first.startswith("envcap viewer: "):
            raise SystemExit(f"{line}: {first or 'no output'}")
        with Chromium(1100, 700) as b:
            b.goto(first.split()[2])
            b.evaluate("window.envcap.ready")
            if b.errors:
                raise SystemExit(f"{line}: the page reported {b.errors}")
            shot = cwd / f"{name}.full.png"
            b.screenshot(shot)
        save(Image.open(shot).crop(VIEW_BOX), name)
    finally:
        server.terminate()
        server.wait(10)


def cropped_to_content(path: Path, pad: int = 8) -> Image.Image:
    """The image at ``path`` without its white margins (``pad`` pixels kept)."""
    img = Image.open(path).convert("RGB")
    box = ImageChops.difference(img, Image.new("RGB", img.size, "white")).getbbox()
    if box is None:
        return img
    return img.crop((max(0, box[0] - pad), max(0, box[1] - pad), min(img.width, box[2] + pad),
                     min(img.height, box[3] + pad)))


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        run("envcap demo --out envcap-demo", work)
        view_screenshot("envcap view envcap-demo --port 0", work, "guide_view_demo.png")

        shutil.copytree(CITY_FILES, work / "city-files")   # the user's own copy, as the guide makes it
        run("envcap streets city-files/city.xml --up-axis z --offset -512000 0 5403000 --out streets", work)
        save(cropped_to_content(work / "streets" / "streets_map.png"), "guide_streets_map.png")
        run("envcap capture streets/scene.toml --out probes --resolution 64 --spacing 10 --webgl2 --scene-gltf",
            work)
        run("envcap evaluate streets/scene.toml --probes probes --out eval --positions 4", work)
        save(Image.open(work / "eval" / "error_vs_lobe.png"), "guide_eval_error_vs_lobe.png")
        view_screenshot("envcap view probes --report eval --port 0", work, "guide_view_streets.png")

        run("envcap capture streets/scene.toml --out city --workers 0 --resolution 32 --webgl2", work)
        view_screenshot("envcap view city --port 0", work, "guide_view_city.png")


if __name__ == "__main__":
    main()
