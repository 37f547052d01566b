"""The scene preview shows surfaces wound inward (issue 10, wall 1: it used to draw them lit as
usual, hiding what the capture gets wrong): a back face seen by the camera is magenta."""

from pathlib import Path

import numpy as np
from PIL import Image

from envcap.core.resources import city_scenes_dir
from envcap.scene import scene_from_dict
from envcap.scene.scene_preview import save_previews

DOC = {"name": "block", "effects": [], "sky": {"type": "uniform", "radiance": 1.0},
       "mesh": {"file": str(city_scenes_dir() / "imported_block"), "up_axis": "z", "rotation_deg": 90.0,
                "offset": [100.0, 0.0, 50.0]},
       "streets": [{"name": "block", "axis": "z", "start": 10.0, "end": 90.0, "width": 10.0, "cross": 100.0}]}


def _magenta_share(path: Path) -> float:
    a = np.asarray(Image.open(path).convert("RGB")).astype(int)
    return float(((a[..., 0] > 2 * a[..., 1] + 60) & (a[..., 2] > 2 * a[..., 1] + 60)).mean())


def test_inward_wound_buildings_are_magenta_in_the_preview(gl_ctx, tmp_path: Path) -> None:
    shares = {}
    for winding in ("auto", "flip"):
        scene = scene_from_dict({**DOC, "mesh": {**DOC["mesh"], "winding": winding}})
        shares[winding] = _magenta_share(save_previews(gl_ctx, scene, tmp_path / f"{winding}.png", width=160))
    assert shares["auto"] < 0.001
    assert shares["flip"] > 0.2
