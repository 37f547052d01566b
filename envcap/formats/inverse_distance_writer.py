"""Probe-set writer ``inverse_distance`` (opt-in: ``envcap capture --inverse-distance``): the probes'
inverse distance, the texture the runtime method ``depth_refine`` reads
(:mod:`envcap.runtime.methods.depth_refine`, GLSL ``envcap_depth_refine``).

* ``inverse_distance.ktx2``: cube-map array ``R16_SFLOAT`` (vkFormat 76, ``"r16f"``), one level
  (the face size N of the set's level 0), layer ``l`` = the probe with ``layer == l`` (the
  layers of ``probes.ktx2``), faces and rows as every envcap cube (``KTXorientation = "rd"``).
  Texel: ``1 / distance`` in 1/m of the probe set's distance channel (``ProbeSet.distance``, the
  radial distance from the probe centre, level 0), 0 where the probe sees the sky and for
  distances that are not positive and finite or are >= :data:`envcap.core.inverse_distance.MAX_DISTANCE` m: the values of
  :func:`envcap.core.inverse_distance.inverse_distance` (the runtime's own), rounded to half floats (relative error
  <= 2^-11 for distances up to 16 km, absolute <= 3e-8 1/m beyond), magnitudes above 65504 1/m
  (distances under 15 micrometres) clamped to 65504.

Frames: a probe of a street at an angle (manifest ``streets[].yaw_deg``) holds its distances in
its street's frame, like its cube in ``probes.ktx2``: read along ``R d``, as the runtime does.

Binding (``docs/engines.md``): upload as a ``GL_TEXTURE_CUBE_MAP_ARRAY`` ``R16F`` (``RED``,
``HALF_FLOAT``; one level, ``depth = 6 L``), filtered ``NEAREST`` both ways, and pass it as the
``dist`` sampler of ``envcap_sample_depth_refine`` (``ENVCAP_DISTANCE_SAMPLER``; the default
``ENVCAP_DISTANCE_FETCH`` reads ``.r`` at level 0).

Manifest entry: ``files.inverse_distance`` (in ``Files.extra``).  Parameters: none.  Needs the
probe set's distance channel: a set read back without its EXR files has none (``ValueError``).
Bytes per probe: ``12 N^2`` (48 KiB at N = 64, 768 KiB at N = 256).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from envcap.core.inverse_distance import inverse_distance
from envcap.formats.ktx2 import write_ktx2
from envcap.formats.writer import FileEntries, ProbeSetWriter

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet

TEXTURE_FILE = "inverse_distance.ktx2"
FORMAT = "r16f"
"""The texture's KTX2 format (:data:`envcap.formats.ktx2.FORMATS`): enough for the check and the
sphere steps of ``depth_refine`` (tolerance 0.1 against a relative rounding of 2^-11)."""
def write_inverse_distance(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write ``inverse_distance.ktx2`` under ``out_dir``; return its entry."""
    if ps.distance is None:
        raise ValueError("inverse_distance needs the probe set's distance channel (ProbeSet.distance is None: "
                         "bake the set, or read it back with its EXR files)")
    d = np.asarray(ps.distance)
    want = (ps.layer_count, 6, ps.resolution, ps.resolution)
    if d.shape != want:
        raise ValueError(f"inverse_distance: distance must have shape {want}, got {d.shape}")
    inv = inverse_distance(d)[..., None]
    write_ktx2(out_dir / TEXTURE_FILE, [inv], layered=True, fmt=FORMAT, clamp=True)
    return {"inverse_distance": TEXTURE_FILE}


WRITER = ProbeSetWriter("inverse_distance", "the probes' inverse distance (R16F) for the depth_refine method",
                        write_inverse_distance, default=False)
