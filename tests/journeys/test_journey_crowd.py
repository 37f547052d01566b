"""Journey: a user writes an avatar with ``envcap avatar``, bakes a street with ``envcap capture``
and renders a lit crowd of that avatar on those probes with ``envcap crowd``, in a fresh working
directory, each output fed unchanged into the next command (docs/guide.md, journey 6).

Checked here: the frames exist and are not blank, the crowd is of the avatar file and uses the
depth-aware lookup because the capture wrote ``inverse_distance.ktx2``, the same seed gives the
same bytes, and the dynamic terms darken the walkers (``--terms neighbours`` against ``--terms
probes``: only walker pixels change, and they get darker on average).  That the GLSL equals its
numpy twin is ``tests/crowd/``."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from PIL import Image

from envcap.core.color import luminance
from envcap.dynamic.avatar_synthetic import write_walker

pytestmark = pytest.mark.slow   # an avatar, a small bake and three small crowd renders: ~8 s on 2 cores
Terminal = Any
"""The ``terminal`` fixture's type (tests/journeys/conftest.py)."""


def _frame(path) -> np.ndarray:
    return np.asarray(Image.open(path), dtype=np.float64) / 255.0


def test_avatar_capture_then_crowd(terminal: Terminal) -> None:
    write_walker(terminal.cwd / "my_walker.glb")     # the user's skinned avatar
    terminal.run("envcap avatar my_walker.glb --out my_walker_envcap.glb")
    terminal.run("envcap capture canyon --out probes --resolution 16 --spacing 50 --quiet")
    assert (terminal.cwd / "probes" / "inverse_distance.ktx2").is_file()

    crowd = "envcap crowd canyon --probes probes --avatars 16 --avatar my_walker_envcap.glb --size 160x100"
    terminal.run(f"{crowd} --frames 2 --out crowd")
    terminal.run(f"{crowd} --frames 2 --out again")
    terminal.run(f"{crowd} --frames 2 --terms probes --out probes_only")

    desc = json.loads((terminal.cwd / "crowd" / "crowd.json").read_text())
    assert desc["avatar"] == "my_walker_envcap.glb" and desc["avatars"] == 16
    assert desc["method"] == "depth_refine" and desc["terms"] == "neighbours"
    for i in range(2):
        name = f"frame_{i:04d}.png"
        lit = _frame(terminal.cwd / "crowd" / name)
        assert lit.shape == (100, 160, 3) and lit.std() > 0.02                     # not blank
        assert (terminal.cwd / "again" / name).read_bytes() == (terminal.cwd / "crowd" / name).read_bytes()
        plain = _frame(terminal.cwd / "probes_only" / name)
        changed = np.abs(lit - plain).max(axis=-1) > 1.5 / 255
        assert 0.001 < changed.mean() < 0.5, changed.mean()                       # the walkers, not the street
        assert luminance(lit[changed]).mean() < luminance(plain[changed]).mean()  # blocked light darkens them
