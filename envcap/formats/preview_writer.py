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


def write_previews(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the PNG previews under ``out_dir / "previews"``; return their entries."""
    (out_dir / "previews").mkdir()
    names = []
    for i in tqdm(range(ps.layer_count), desc="previews", unit="probe", disable=None):
        name = f"previews/probe_{i:03d}.png"
        cube_cross_png(out_dir / name, np.asarray(ps.levels[0][i]))
        names.append(name)
    cube_cross_png(out_dir / "previews/sky.png", np.asarray(ps.sky_levels[0]))
    contact_sheet_png(out_dir / "previews/contact_sheet.png", [np.asarray(a) for a in ps.levels[0]], layer_labels(ps))
    return {"previews": names, "sky_preview": "previews/sky.png", "contact_sheet": "previews/contact_sheet.png"}


WRITER = ProbeSetWriter("previews", "PNG crosses of each probe and the sky, and a contact sheet", write_previews)
