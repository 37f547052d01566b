"""Probe-set writer ``exr``: one OpenEXR cube map per probe, ``exr/probe_NNN.exr``.

Level 0 of layer ``NNN``: R, G, B, A as half floats and, when the set has distances, Z = the
radial distance in meters (float32); orientation as in :mod:`envcap.formats.exr_cube`.
Manifest entry: ``files.exr`` (one path per layer, in layer order).  Parameters: none (RGBA is
always half: the probe array is RGBA16F anyway).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from envcap.formats.exr_cube import write_exr_cube
from envcap.formats.writer import FileEntries, ProbeSetWriter

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet


def write_exr_probes(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write one EXR cube per probe under ``out_dir / "exr"``; return ``{"exr": [paths]}``."""
    (out_dir / "exr").mkdir()
    names = []
    for i in tqdm(range(ps.layer_count), desc="probe EXR", unit="probe", disable=None):
        name = f"exr/probe_{i:03d}.exr"
        dist = None if ps.distance is None else np.asarray(ps.distance[i])
        write_exr_cube(out_dir / name, np.asarray(ps.levels[0][i]), dist, half=True)
        names.append(name)
    return {"exr": names}


WRITER = ProbeSetWriter("exr", "one OpenEXR cube per probe: level 0 RGBA (half) and distance Z (m)", write_exr_probes)
