"""Probe-set writer ``previews``: PNG previews of level 0 (tone-mapped, see ``docs/formats.md``).

* ``previews/probe_NNN.png``: the inside-view cross of each probe (sky shown as a checkerboard);
* ``previews/sky.png``: the sky's cross;
* ``previews/contact_sheet.png``: all probes on one sheet with one exposure, labeled
  ``"<street> #<layer>"``.

Manifest entries: ``files.previews`` (per layer), ``files.sky_preview``, ``files.contact_sheet``.
Parameters: none (automatic exposure).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from envcap.formats.png_preview import contact_sheet_png, cube_cross_png
from envcap.formats.writer import FileEntries, ProbeSetWriter

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet


def layer_labels(ps: ProbeSet) -> list[str]:
    """``"<street> #<layer>"`` for each layer of ``ps``, in layer order."""
    labels = [f"layer {i}" for i in range(ps.layer_count)]
    for st in ps.manifest.streets:
        for pr in st.probes:
            labels[pr.layer] = f"{st.name} #{pr.layer}"
    return labels


PREVIEW_DIR = "previews"


def write_probe_preview(out_dir: Path, layer: int, rgba: NDArray) -> str:
    """Write layer ``layer``'s cross (``rgba`` ``(6, N, N, 4)``, level 0) under ``out_dir`` (whose
    ``previews/`` exists); return its name."""
    name = f"{PREVIEW_DIR}/probe_{layer:03d}.png"
    cube_cross_png(out_dir / name, np.asarray(rgba))
    return name


def write_set_previews(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the previews of the whole set (the sky's cross, the contact sheet) under
    ``out_dir`` (whose ``previews/`` exists); return their entries."""
    cube_cross_png(out_dir / PREVIEW_DIR / "sky.png", np.asarray(ps.sky_levels[0]))
    contact_sheet_png(out_dir / PREVIEW_DIR / "contact_sheet.png", [np.asarray(a) for a in ps.levels[0]],
                      layer_labels(ps))
    return {"sky_preview": f"{PREVIEW_DIR}/sky.png", "contact_sheet": f"{PREVIEW_DIR}/contact_sheet.png"}


def write_previews(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the PNG previews under ``out_dir / "previews"``; return their entries."""
    (out_dir / PREVIEW_DIR).mkdir()
    names = []
    for i in tqdm(range(ps.layer_count), desc="previews", unit="probe", disable=None):
        names.append(write_probe_preview(out_dir, i, ps.levels[0][i]))
    return {"previews": names, **write_set_previews(out_dir, ps)}


WRITER = ProbeSetWriter("previews", "PNG crosses of each probe and the sky, and a contact sheet", write_previews)
