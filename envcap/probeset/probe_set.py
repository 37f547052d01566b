"""A probe set in memory: the manifest and the texture arrays, and their consistency check."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.probeset.manifest import Manifest, check_manifest


@dataclass
class ProbeSet:
    """A probe set in memory.

    ``manifest``: the typed manifest (:class:`envcap.probeset.manifest.Manifest`).
    ``levels[k]``: probe-array mip level ``k``, float32 ``(L, 6, N_k, N_k, 4)``, premultiplied
    RGBA, ``N_k = max(1, N >> k)``; layer ``l`` is the probe with ``layer == l``.
    ``distance``: ``(L, 6, N, N)`` float32 radial distance in meters from the probe center, 0
    where alpha = 0 (level 0 only), or ``None``.  ``sky_levels[k]``: sky mip level ``k``,
    float32 ``(6, M_k, M_k, 4)`` with alpha = 1.
    """

    manifest: Manifest
    levels: list[NDArray]
    distance: NDArray | None
    sky_levels: list[NDArray]

    @property
    def layer_count(self) -> int:
        return int(self.levels[0].shape[0])

    @property
    def resolution(self) -> int:
        return int(self.levels[0].shape[2])


def check_chain(levels: Any, layered: bool, what: str) -> int:
    """Check a mip chain: level 0 ``(L, 6, N, N, 4)`` (``layered``) or ``(6, N, N, 4)``, level
    ``k`` of size ``max(1, N >> k)``, all finite; return ``N`` (``ValueError`` otherwise)."""
    if not isinstance(levels, (list, tuple)) or not levels:
        raise ValueError(f"{what}: need a non-empty list of mip levels")
    a0 = np.asarray(levels[0])
    nd = 5 if layered else 4
    if a0.ndim != nd or a0.shape[-4] != 6 or a0.shape[-1] != 4 or a0.shape[-2] != a0.shape[-3] or a0.shape[-2] < 1:
        raise ValueError(f"{what}: level 0 must be {'(L, 6, N, N, 4)' if layered else '(6, N, N, 4)'}, got {a0.shape}")
    n = a0.shape[-2]
    for k, lev in enumerate(levels):
        a = np.asarray(lev)
        want = a0.shape[:-3] + (max(1, n >> k), max(1, n >> k), 4)
        if a.shape != want:
            raise ValueError(f"{what}: level {k} must have shape {want}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{what}: level {k} contains NaN or Inf")
    return n


def check_probe_set(ps: ProbeSet) -> None:
    """Check the manifest, the chains and the distances of ``ps`` against each other
    (``ValueError`` naming the first disagreement)."""
    m = ps.manifest
    layers = check_manifest(m)
    n = check_chain(ps.levels, True, "probe levels")
    check_chain(ps.sky_levels, False, "sky levels")
    L = ps.levels[0].shape[0]
    if L != layers or L < 1:
        raise ValueError(f"probe levels have {L} layers but the manifest lists {layers} probes")
    if n != m.resolution or len(ps.levels) != len(m.levels):
        raise ValueError(
            f"probe levels ({len(ps.levels)} levels of {n}) disagree with the manifest "
            f"({len(m.levels)} levels of {m.resolution})"
        )
    if ps.distance is not None:
        d = np.asarray(ps.distance)
        if d.shape != (L, 6, n, n):
            raise ValueError(f"distance must have shape {(L, 6, n, n)}, got {d.shape}")
        if not np.all(np.isfinite(d)) or np.any(d < 0):
            raise ValueError("distance must be finite and >= 0 (meters)")
        if np.any((np.asarray(ps.levels[0])[..., 3] == 0) & (d != 0)):
            raise ValueError("distance must be 0 where alpha is 0 (sky)")
