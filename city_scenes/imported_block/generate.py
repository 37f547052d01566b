"""Regenerate the PLY boxes of the bundled ``imported`` scene (run from this directory).

The boxes are written Z-up (as exported by many DCC tools), in meters, around the file origin:
a row of houses along file +X on each side of a 10 m street (file y in [-15, -5] and [5, 15]).
``../imported.toml`` brings them into the envcap frame with up_axis = "z", rotation_deg = 90 and
offset = [100, 0, 50], which puts the street along world Z at x = 100.
Each box has sRGB vertex colors (one color per box).
"""

import numpy as np
import trimesh

rng = np.random.default_rng(5)
x = -40.0
i = 0
while x < 40.0 - 1e-9:
    w = min(float(rng.uniform(8.0, 14.0)), 40.0 - x)
    for side, (y0, y1) in enumerate(((5.0, 15.0), (-15.0, -5.0))):
        h = float(rng.uniform(8.0, 20.0))
        box = trimesh.creation.box(bounds=[[x, y0, 0.0], [x + w, y1, h]])
        rgb = (rng.uniform(90, 230, 3)).astype(np.uint8)
        box.visual.vertex_colors = np.tile(np.r_[rgb, 255], (len(box.vertices), 1))
        box.export(f"box_{i:02d}_{side}.ply")
    x += w
    i += 1
