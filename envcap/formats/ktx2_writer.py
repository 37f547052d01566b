"""Probe-set writer ``ktx2`` (required): ``probes.ktx2`` and ``sky.ktx2``, every mip level.

* ``probes.ktx2``: cube-map array RGBA16F, one layer per probe, premultiplied alpha (the probe
  data must fit half floats, +-65504);
* ``sky.ktx2``: plain cube map RGBA32F (the sun can exceed the half-float range).

A set baked with a rung ladder (``manifest.ladder``, :class:`envcap.probeset.ladder_table.LadderTable`)
writes its rung textures instead: ``probes.ktx2`` with ``R`` layers per probe (layer ``p R + r``)
and ``sky.ktx2`` as an ``R``-layer cube-map array, both with the ladder's levels (down to 8^2).

Both carry only the key/values the KTX 2.0 specification defines (``KTXorientation``,
``KTXwriter``), so that ``ktx validate`` passes them without warnings; what they are is said by
the manifest beside them (``manifest.json``: ``files.probes``, ``files.sky``, the lobe ladder,
the probes' layers).  Manifest entries: ``files.probes``, ``files.sky``.  Parameters: none.
Layout in ``docs/formats.md``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from envcap.formats.ktx2 import write_ktx2
from envcap.formats.writer import FileEntries, ProbeSetWriter

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet

PROBES_FILE = "probes.ktx2"
SKY_FILE = "sky.ktx2"


def write_ktx2_textures(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the probe array and the sky chain under ``out_dir``; return their entries."""
    rungs = ps.rungs is not None   # a rung ladder (manifest.ladder): R layers per probe, an R-layer sky array
    write_ktx2(out_dir / PROBES_FILE, [np.asarray(a) for a in (ps.rungs if rungs else ps.levels)], layered=True,  # type: ignore[union-attr]
               fmt="rgba16f", premultiplied=True)
    write_ktx2(out_dir / SKY_FILE, [np.asarray(a) for a in (ps.sky_rungs if rungs else ps.sky_levels)],  # type: ignore[union-attr]
               layered=rungs, fmt="rgba32f")
    return {"probes": PROBES_FILE, "sky": SKY_FILE}


WRITER = ProbeSetWriter("ktx2", "KTX2 probe array (RGBA16F) and sky (RGBA32F), all levels",
                        write_ktx2_textures, required=True)
