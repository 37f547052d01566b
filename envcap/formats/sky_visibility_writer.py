"""Probe-set writer ``sky_visibility`` (opt-in: ``envcap capture --sky-visibility``): the visibility
moments that correct the composite after filtering when the sky changes after the bake
(``docs/lobes.md``, "A sky that changes"; runtime: :mod:`envcap.runtime.sky_visibility`, GLSL
``envcap_sky_visible``).

* ``sky_visibility.ktx2``: cube-map array RGBA16F, the packed
  :meth:`envcap.prefilter.sky_visibility.SkyVisibility.packed_levels` of the captures' alpha
  (their level 0) on the set's rung ladder (``manifest.ladder``; a ``paper`` set: the
  ``half_octave`` ladder of its face size, as :func:`envcap.runtime.rungs.rung_chains_of` builds
  it), SH order :data:`ORDER`: mip ``k`` is rung level ``first_level + k``; probe ``p`` has
  ``layers_per_probe`` layers from ``p * layers_per_probe``; channel ``q = r n_sh + c`` (rung layer
  ``r``, coefficient ``c``) is component ``q % 4`` of layer ``q // 4``.
* ``sky_visibility.json``: ``order``, ``first_level``, ``layers_per_probe``, ``max_power``,
  ``ladder`` (:meth:`envcap.core.rungs.RungLadder.to_manifest`), ``baked_sky_sh`` (the set's sky
  map projected on the same basis, ``(n_sh, 3)``: the base of :func:`envcap.runtime.sky_visibility.sky_delta`),
  ``gradient_step``, ``basis``, ``layout``; a set with an angled street (some ``yaw_deg`` other
  than 0) also ``probe_yaw_deg`` (per layer) and ``frame``.

Frames: each probe's moments are in its street's frame, like its cube (the manifest's
``streets[].yaw_deg``, :mod:`envcap.core.street_frame`): texel ``f`` holds the moments of the
world direction ``R^T f``.  ``baked_sky_sh`` is the world's sky.  The runtime reads a probe's
moments along ``R d`` and turns the sky's coefficients by ``R``
(:func:`envcap.runtime.sky_visibility.sky_visible` ``yaw_deg``, GLSL ``envcap_sky_visible``
``frame``; ``docs/lobes.md``, "A sky that changes").

Manifest entries: ``files.sky_visibility``, ``files.sky_visibility_table``.  Parameters: none.
Bytes per probe: :meth:`~envcap.prefilter.sky_visibility.SkyVisibility.bytes_per_probe`
(252 KiB at order 1 for every N >= 64).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from envcap.core.rungs import rung_ladder
from envcap.formats.ktx2 import write_ktx2
from envcap.formats.writer import FileEntries, ProbeSetWriter
from envcap.prefilter.sky_visibility import (
    DEFAULT_MAX_POWER,
    prefilter_sky_visibility,
    project_sh,
)

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet

ORDER = 1
"""SH order stored: l <= 1 (4 scalars per texel), the measured choice (``docs/lobes.md``)."""
GRADIENT_STEP = 0.5
"""``h = GRADIENT_STEP / sqrt(w + 2)``: the runtime's central-difference step (the same constant as
:data:`envcap.runtime.sky_visibility.GRADIENT_STEP`, which ``tests`` pin to this one)."""
TEXTURE_FILE = "sky_visibility.ktx2"
TABLE_FILE = "sky_visibility.json"


def write_sky_visibility(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the moments texture and its table under ``out_dir``; return their entries."""
    table = ps.manifest.ladder
    ladder = table.rung_ladder() if table is not None else rung_ladder(ps.resolution, "half_octave")
    cap = np.asarray(ps.levels[0])
    if cap.shape[-1] < 4:
        raise ValueError(f"sky visibility needs the captures' alpha, the probe set has {cap.shape[-1]} channels")
    vis = prefilter_sky_visibility(cap[..., 3], ladder, ORDER, DEFAULT_MAX_POWER)
    write_ktx2(out_dir / TEXTURE_FILE, vis.packed_levels(), layered=True, fmt="rgba16f")
    meta = {"order": ORDER, "first_level": vis.first_level, "layers_per_probe": vis.layers_per_probe,
            "max_power": DEFAULT_MAX_POWER, "ladder": ladder.to_manifest(),
            "baked_sky_sh": project_sh(np.asarray(ps.sky_levels[0], np.float64)[..., :3], ORDER).tolist(),
            "gradient_step": GRADIENT_STEP,
            "basis": "real SH, z polar, l = 0..order, m = -l..l (envcap.prefilter.sky_visibility.sh_basis)",
            "layout": "mip k = rung level first_level + k; layer p * layers_per_probe + q // 4, component q % 4, "
                      "q = r * (order + 1)^2 + c"}
    yaws = {p.layer: st.frame_yaw_deg for st in ps.manifest.streets for p in st.probes}
    if any(yaws.values()):                        # unframed sets: today's table, byte for byte
        meta["probe_yaw_deg"] = [yaws.get(i, 0.0) for i in range(ps.layer_count)]
        meta["frame"] = ("probe p's moments are in its street's frame (yaw probe_yaw_deg[p], manifest streets[].yaw_deg): "
                         "read them along R d, turn the world's sky coefficients by R")
    (out_dir / TABLE_FILE).write_text(json.dumps(meta, indent=1))
    return {"sky_visibility": TEXTURE_FILE, "sky_visibility_table": TABLE_FILE}


WRITER = ProbeSetWriter("sky_visibility", "visibility moments (RGBA16F) for the composite under a changed sky",
                        write_sky_visibility, default=False)
