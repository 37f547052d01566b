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
    ``rungs`` / ``sky_rungs``: a set baked with a rung ladder (``manifest.ladder``, else ``None``):
    ``rungs[j]`` ``(L R, 6, N_j, N_j, 4)``, layer ``l R + r`` = rung ``j R + r`` of probe ``l``;
    ``sky_rungs[j]`` ``(R, 6, N_j, N_j, 4)``.  ``levels`` and ``sky_levels`` are then their layers
    ``r = 0`` (views: the capture at level 0, one lobe per level).
    """

    manifest: Manifest
    levels: list[NDArray]
    distance: NDArray | None
    sky_levels: list[NDArray]
    rungs: list[NDArray] | None = None
    sky_rungs: list[NDArray] | None = None

    @property
    def layer_count(self) -> int:
        return int(self.levels[0].shape[0])

    @property
    def resolution(self) -> int:
        return int(self.levels[0].shape[2])


ALPHA_TOLERANCE = 2.0 ** -10
"""How far above 1 a stored alpha may lie (rounding of a filtered coverage): one half-float step."""

_BLOCK_TEXELS = 1 << 22
"""Texels checked at once by :func:`check_texels` (bounds its temporaries to a few tens of MB)."""


_RULES = {"nonfinite": "are NaN/Inf", "negative": "have negative R, G or B (radiance must be >= 0)",
          "alpha": "have alpha outside [0, 1]"}


def check_texels(levels: list[NDArray], layered: bool, what: str) -> None:
    """Check every texel of a premultiplied RGBA radiance chain; ``ValueError`` naming ``what``
    (a file), the first layer and level at fault (lowest level first) and the count of bad texels there.

    ``levels[k]``: ``(L, 6, N_k, N_k, 4)`` when ``layered``, else ``(6, N_k, N_k, 4)``.  Rules,
    reported in this order: every component finite; R, G, B >= 0 (radiance); alpha in
    ``[0, 1 + ALPHA_TOLERANCE]`` (a coverage, with the rounding of a stored filtered value).
    E.g. ``probes.ktx2: layer 3, level 2: 17 of 384 texels are NaN/Inf (40 in all, in 2 layers)``.
    """
    first: dict[str, str] = {}        # rule -> "level k, layer l: c of t texels"
    total: dict[str, int] = {}
    layers: dict[str, set[int]] = {}
    extreme: dict[str, str] = {}
    for k, lev in enumerate(levels):
        a = np.asarray(lev)
        a = a if layered else a[None]
        per_layer = int(np.prod(a.shape[1:-1]))
        step = max(1, _BLOCK_TEXELS // max(per_layer, 1))
        for b0 in range(0, a.shape[0], step):
            blk = a[b0:b0 + step]
            rgb, alpha = blk[..., :3], blk[..., 3]
            with np.errstate(invalid="ignore"):
                rules = {"nonfinite": ~np.isfinite(blk).all(axis=-1),
                         "negative": (rgb < 0).any(axis=-1),
                         "alpha": (alpha < 0) | (alpha > 1 + ALPHA_TOLERANCE)}
            for rule, bad in rules.items():
                counts = bad.reshape(bad.shape[0], -1).sum(axis=1)
                hit = np.flatnonzero(counts)
                if hit.size == 0:
                    continue
                if rule not in first:
                    place = f"layer {b0 + int(hit[0])}, level {k}" if layered else f"level {k}"
                    first[rule] = f"{place}: {int(counts[hit[0]])} of {per_layer} texels"
                    extreme[rule] = {"nonfinite": "", "negative": f"; smallest {float(np.min(rgb[bad])):g}",
                                     "alpha": f"; e.g. {float(alpha[bad][0]):g}"}[rule]
                total[rule] = total.get(rule, 0) + int(counts.sum())
                layers.setdefault(rule, set()).update((b0 + hit).tolist())
    for rule, words in _RULES.items():
        if rule in first:
            scope = f"{total[rule]} in all" + (f", in {len(layers[rule])} layer(s)" if layered else "")
            raise ValueError(f"{what}: {first[rule]} {words} ({scope}{extreme[rule]})")


def check_chain(levels: Any, layered: bool, what: str) -> int:
    """Check a mip chain: level 0 ``(L, 6, N, N, 4)`` (``layered``) or ``(6, N, N, 4)``, level
    ``k`` of size ``max(1, N >> k)``, its texels by :func:`check_texels`; return ``N``
    (``ValueError`` otherwise)."""
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
    check_texels(list(levels), layered, what)
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
    if m.ladder is not None or ps.rungs is not None:
        check_rungs(ps, L)
    if ps.distance is not None:
        d = np.asarray(ps.distance)
        if d.shape != (L, 6, n, n):
            raise ValueError(f"distance must have shape {(L, 6, n, n)}, got {d.shape}")
        if not np.all(np.isfinite(d)) or np.any(d < 0):
            raise ValueError("distance must be finite and >= 0 (meters)")
        if np.any((np.asarray(ps.levels[0])[..., 3] == 0) & (d != 0)):
            raise ValueError("distance must be 0 where alpha is 0 (sky)")


def check_rungs(ps: ProbeSet, probes: int) -> None:
    """Check the rung textures of ``ps`` against ``manifest.ladder`` (``ValueError``)."""
    t = ps.manifest.ladder
    if t is None or ps.rungs is None or ps.sky_rungs is None:
        raise ValueError("a rung-ladder probe set needs manifest.ladder, rungs and sky_rungs together")
    r = t.per_level
    for name, lv, layers in (("probe rungs", ps.rungs, probes * r), ("sky rungs", ps.sky_rungs, r)):
        want = [(layers, 6, s, s, 4) for s in t.sizes]
        if [np.shape(a) for a in lv] != want:
            raise ValueError(f"{name}: levels must have shapes {want}, got {[np.shape(a) for a in lv]}")
        check_texels(list(lv), True, name)
