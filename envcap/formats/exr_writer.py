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
from numpy.typing import NDArray
from tqdm import tqdm

from envcap.formats.exr_cube import write_exr_cube
from envcap.formats.writer import FileEntries, ProbeSetWriter

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet


EXR_DIR = "exr"


def exr_name(layer: int) -> str:
    """The file of layer ``layer``, relative to the probe-set directory."""
    return f"{EXR_DIR}/probe_{layer:03d}.exr"


def write_probe_exr(out_dir: Path, layer: int, rgba: NDArray, distance: NDArray | None) -> str:
    """Write layer ``layer``'s EXR (``rgba`` ``(6, N, N, 4)`` level 0, ``distance`` ``(6, N, N)``
    m or ``None``) under ``out_dir`` (whose ``exr/`` exists); return its name."""
    name = exr_name(layer)
    write_exr_cube(out_dir / name, np.asarray(rgba), None if distance is None else np.asarray(distance), half=True)
    return name


def write_exr_probes(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write one EXR cube per probe under ``out_dir / "exr"``; return ``{"exr": [paths]}``."""
    (out_dir / EXR_DIR).mkdir()
    names = []
    for i in tqdm(range(ps.layer_count), desc="probe EXR", unit="probe", disable=None):
        names.append(write_probe_exr(out_dir, i, ps.levels[0][i], None if ps.distance is None else ps.distance[i]))
    return {"exr": names}


WRITER = ProbeSetWriter("exr", "one OpenEXR cube per probe: level 0 RGBA (half) and distance Z (m)", write_exr_probes)
