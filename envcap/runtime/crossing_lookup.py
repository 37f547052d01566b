"""The lookup inside a crossing: a street with the crossing's shared probe among its probes.

The numpy twin of ``shaders/runtime/envcap_crossing.glsl`` (docs/crossings.md, "In your shader").
A position inside crossing ``k`` (the street map's crossing id, :func:`envcap.runtime.street_map.
crossing_index`) is looked up, in the default mode ``shared`` (:data:`envcap.evaluate.predict.
CROSSING_MODE`), on the street it walks on with the crossing probe inserted among that street's
probes (:func:`crossing_street`, GLSL ``envcap_crossing_street``) when the street runs in its
owner's frame (the owner itself or a street of the same yaw), else on the crossing probe alone in
its owner's frame (:func:`probe_street`, GLSL ``envcap_probe_street``).  Any registered method
(:mod:`envcap.runtime.methods`) then runs on the result.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from envcap.runtime.limits import MAX_PROBES
from envcap.runtime.street import RuntimeStreet


def crossing_street(street: RuntimeStreet, position: ArrayLike, layer: int) -> RuntimeStreet:
    """``street`` with the probe of layer ``layer`` at ``position`` (3,) m (the street's frame
    coordinates) among its probes, in along order (after probes at the same along coordinate).

    Its planes are those of the street's probe nearest to it along the street (ties: the lower
    index), the ground extended along that probe's slope to the new probe.  A street that already
    holds ``layer`` is returned as is; a full one (``MAX_PROBES``) first drops its end probe farther
    from the new probe along the street (ties: the last)."""
    pos = np.asarray(position, np.float64).reshape(3)
    if not np.all(np.isfinite(pos)):
        raise ValueError(f"crossing probe position must be finite, got {pos}")
    if np.any(street.layers == layer):
        return street
    a = street.along
    s_all = street.along_coords
    near = int(np.argmin(np.abs(s_all - pos[a])))
    row = street.planes[near].copy()
    slope = float(street.slopes[near])
    row[2] += slope * (pos[a] - s_all[near])
    keep = np.arange(s_all.size)
    if s_all.size == MAX_PROBES:
        keep = keep[1:] if abs(pos[a] - s_all[0]) > abs(pos[a] - s_all[-1]) else keep[:-1]
    j = int(np.count_nonzero(s_all[keep] <= pos[a]))
    ins = (lambda arr, v: np.insert(arr[keep], j, v, axis=0))
    return RuntimeStreet(a, ins(street.positions, pos), ins(street.planes, row),
                         ins(street.layers, int(layer)), street.yaw_deg, street.origin_xz,
                         ins(street.slopes, slope))


def probe_street(street: RuntimeStreet, layer: int) -> RuntimeStreet:
    """``street`` cut to its probe of layer ``layer`` alone (the crossing probe in its owner's
    frame); a street without that layer is returned as is."""
    idx = np.flatnonzero(street.layers == layer)
    if idx.size == 0:
        return street
    i = idx[:1]
    return RuntimeStreet(street.along, street.positions[i], street.planes[i], street.layers[i], street.yaw_deg,
                         street.origin_xz, street.slopes[i])
