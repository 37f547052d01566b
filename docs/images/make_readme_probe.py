"""Regenerate docs/images/readme_probe_canyon.png: one canyon probe (64^2), composited with its sky.

Run: python3 docs/images/make_readme_probe.py
"""

from pathlib import Path

import numpy as np
from PIL import Image

from envcap.capture.renderer import CubeCapture
from envcap.formats.png_preview import cube_cross_png
from envcap.scene import load_scene

OUT = Path(__file__).resolve().parent / "readme_probe_canyon.png"


def main() -> None:
    scene = load_scene("canyon")
    sky = scene.sky.build()
    with CubeCapture.from_scene(scene, 64, sky=sky) as cap:
        probe = cap.capture([0.0, 2.0, 0.0])
    sky_cube = sky.cube(64)
    rgb = probe.rgba[..., :3] + (1.0 - probe.rgba[..., 3:]) * sky_cube
    cube_cross_png(OUT, np.concatenate([rgb, np.ones_like(rgb[..., :1])], axis=-1))
    im = Image.open(OUT)
    im.resize((im.width * 2, im.height * 2), Image.NEAREST).save(OUT, optimize=True)
    print(OUT)


if __name__ == "__main__":
    main()
