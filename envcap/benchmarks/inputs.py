"""Real benchmark inputs for the cosine-lobe filter: a captured street probe and a sky with a sun."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.capture.renderer import CubeCapture
from envcap.scene import load_scene


def real_inputs(n: int, ctx: Any = None, scene_name: str = "canyon",
                position: tuple[float, float, float] = (0.0, 2.0, 0.0)) -> dict[str, NDArray[np.float64]]:
    """``{"street": (6, n, n, 4), "sky_sun": (6, n, n, 4)}`` float64 cubes.

    ``street``: the probe captured at ``position`` in the bundled scene (premultiplied RGBA,
    alpha 0 where sky shows) composited over that scene's sky *with* its sun (what a runtime
    lookup sees); ``sky_sun``: the scene's Preetham sky with its sun splatted in (alpha 1).
    """
    scene = load_scene(scene_name)
    sky = scene.sky.build()
    rgb = np.asarray(sky.cube(n), np.float64)
    sky_rgba = np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,))], -1)
    cap = CubeCapture.from_scene(scene, n, sky=sky, ctx=ctx)
    try:
        street = np.asarray(cap.capture(position).rgba, np.float64)
    finally:
        cap.release()
    env = street + (1.0 - street[..., 3:4]) * sky_rgba
    env[..., 3] = street[..., 3]
    return {"street": env, "sky_sun": sky_rgba}
