"""Probe-set writer ``webgl2`` (opt-in: ``envcap capture --webgl2``): ``probes_atlas.ktx2``, the probe
array for APIs without cube-map arrays (WebGL2, three.js).

* ``probes_atlas.ktx2``: a 2D texture array RGBA16F of one level, layer ``probe * 6 + face``
  (GL face order), each layer the face atlas of that face's whole mip chain with 1-texel seam
  borders (layout: :mod:`envcap.formats.face_atlas`); premultiplied alpha, as ``probes.ktx2``.
  Sample it with ``shaders/runtime/envcap_face_atlas.glsl`` (the WebGL2 target of
  :mod:`envcap.runtime.shader_targets` does): LINEAR filtering, CLAMP_TO_EDGE, no mipmaps.
  Same values as ``probes.ktx2`` looked up trilinearly, within the tolerance stated in
  ``docs/engines.md``.  The sky needs no atlas: WebGL2 has cube maps (``sky.ktx2``).

Manifest entry: ``files.probes_atlas``.  Parameters: none.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from envcap.formats.face_atlas import face_atlas
from envcap.formats.ktx2 import write_ktx2_array
from envcap.formats.writer import FileEntries, ProbeSetWriter

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet

ATLAS_FILE = "probes_atlas.ktx2"


def write_probe_atlas(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the probes' face atlases under ``out_dir``; return ``{"probes_atlas": ATLAS_FILE}``."""
    atlas = face_atlas([np.asarray(a) for a in ps.levels], np.float16)
    write_ktx2_array(out_dir / ATLAS_FILE, atlas, fmt="rgba16f", premultiplied=True)
    return {"probes_atlas": ATLAS_FILE}


WRITER = ProbeSetWriter("webgl2", "probe face atlases as a KTX2 2D array (RGBA16F) for WebGL2 / three.js",
                        write_probe_atlas, default=False)
