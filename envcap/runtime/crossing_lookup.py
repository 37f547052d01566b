"""The lookup inside a crossing: a street with the crossing's shared probe among its probes.

The numpy twin of ``shaders/runtime/envcap_crossing.glsl`` (docs/crossings.md, "In your shader").
A position inside crossing ``k`` (the street map's crossing id, :func:`envcap.runtime.street_map.
crossing_index`) is looked up, in the default mode ``shared`` (:data:`envcap.evaluate.predict.
CROSSING_MODE`), on the street it walks on with the crossing probe inserted among that street's
probes (:func:`crossing_street`, GLSL ``envcap_crossing_street``) when the street runs in its
owner's frame (the owner itself or a street of the same yaw), else on the crossing probe alone in
its owner's frame (:func:`probe_street`, GLSL ``envcap_probe_street``).  Any registered method
(:mod:`envcap.runtime.methods`) then runs on the result.

Mode ``direction`` chooses per direction: each direction ``d`` from ``x`` is looked up on the
meeting street it looks down, the one whose facades the ray leaves last (:func:`facade_exit`,
GLSL ``envcap_facade_exit``: the largest exit distance; ties, e.g. rays with no plan component,
go to the first street, the crossing's owner).  Each direction still costs one lookup.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.runtime.limits import MAX_PROBES
from envcap.runtime.parallax import frame_direction
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


NO_EXIT = 1e30
"""What :func:`facade_exit` gives a ray parallel to the facades (GLSL ``ENVCAP_NO_EXIT``)."""


def facade_exit(street: RuntimeStreet, x: ArrayLike, d: ArrayLike) -> NDArray[np.float64]:
    """Per world direction ``d`` ``(M, 3)``: the distance (m, along ``d``) at which the ray from
    the WORLD point ``x`` (3,) leaves ``street`` through one of its facades (the planes of its
    probe nearest to ``x`` along it, in its frame); :data:`NO_EXIT` for a ray parallel to the
    facades (or NaN), 0 for a point already outside them.  GLSL ``envcap_facade_exit`` (float32,
    street-local)."""
    xf = street.to_frame(np.asarray(x, np.float64).reshape(3))
    df = frame_direction(np.asarray(d, np.float64).reshape(-1, 3), street.frame)
    i = int(street.nearest(xf))
    fmin, fmax = street.planes[i, 0], street.planes[i, 1]
    c = 2 - street.along
    a, dc = xf[c], df[:, c]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(dc > 0.0, (fmax - a) / dc, np.where(dc < 0.0, (fmin - a) / dc, NO_EXIT))
        return np.where(t > 0.0, np.minimum(t, NO_EXIT), np.where(t <= 0.0, 0.0, NO_EXIT))


def street_per_direction(streets: list[RuntimeStreet], x: ArrayLike, d: ArrayLike) -> NDArray[np.int64]:
    """Per world direction ``d`` ``(M, 3)``: the index in ``streets`` (the meeting streets, owner
    first) of the street the ray from ``x`` looks down: the largest :func:`facade_exit` (ties: the
    lower index)."""
    t = np.stack([facade_exit(st, x, d) for st in streets])
    return np.argmax(t, axis=0).astype(np.int64)
