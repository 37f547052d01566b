"""The crowd's output directory: ``frame_0000.png`` ... (tone-mapped, one exposure for the whole
run so that frames compare: :func:`envcap.formats.png_preview.auto_exposure` of the first) and ``crowd.json`` (what was drawn: seed, terms, method, avatar, the
walkers' feet per frame, timings).  Written into the staged directory of
:func:`envcap.outputs.atomic_output_dir` (nothing half-written)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from envcap.formats.png_preview import tonemap

FRAME_NAME = "frame_{:04d}.png"
"""File name of frame ``i``."""
DESCRIPTION = "crowd.json"
"""The crowd's description."""


def write_frame(folder: Path, index: int, rgb: NDArray[np.float32], exposure: float) -> Path:
    """Tone-map ``rgb`` ``(H, W, 3)`` (row 0 at the top) and write it as frame ``index``."""
    path = Path(folder) / FRAME_NAME.format(index)
    Image.fromarray(np.ascontiguousarray(tonemap(rgb, exposure))).save(path, format="PNG")
    return path


def write_description(folder: Path, description: dict[str, Any]) -> Path:
    """``crowd.json`` (strict JSON: no NaN)."""
    path = Path(folder) / DESCRIPTION
    path.write_text(json.dumps(description, indent=1, allow_nan=False) + "\n")
    return path
