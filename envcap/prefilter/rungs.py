"""Filter cubes into a rung ladder (:class:`envcap.core.rungs.RungLadder`): ``R`` cosine lobes per
mip level, as the layers of a mip-mapped cube-map array (``docs/lobes.md``, "Ladder modes").

Rung ``i = j R + r`` of probe ``p`` is layer ``p R + r`` of level ``j``: the normalized
``cos^powers[i]`` average (:mod:`envcap.prefilter.exact` defines it) on ``N_j``-texel faces.
Rung 0 is the input itself.  Levels ``j >= 1`` of layer ``r`` are one chain of
:func:`envcap.prefilter.fast.prefilter_many` on the ladder ``(powers[0], powers[R + r],
powers[2R + r], ..)`` (its level 0, the input, is dropped); the level-0 rungs ``r >= 1`` are
filtered at full resolution by :func:`envcap.prefilter.fast.prefilter_level`, one cube at a time.

Sky-weighted alpha (``sky=``, ``docs/lobes.md``, "Composite after filtering"): the runtime
composites after filtering, ``street_w + (1 - alpha_w) sky_w``, which misses the covariance of
alpha and the sky under the lobe.  With the alpha of every filtered rung replaced by
``filter(alpha Y) / filter(Y)`` (``Y``: the sky's luminance) the same composite is exact in
luminance for that sky, and for any uniform scaling of it; no extra texel, no runtime change.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.color import luminance
from envcap.core.lobes import LobeLadder
from envcap.core.rungs import RungLadder, rung_ladder
from envcap.gpu.context import create_context
from envcap.prefilter.exact import check_finite_cube
from envcap.prefilter.fast import Quality, prefilter_level, prefilter_many

__all__ = ["prefilter_rungs", "sky_weighted_alpha", "rung_textures"]


def prefilter_rungs(cubes: ArrayLike, ladder: RungLadder, quality: Quality = "default", ctx: Any = None,
                    progress: bool | None = None, sky: ArrayLike | None = None) -> list[NDArray[np.float32]]:
    """The rung levels of ``P`` cubes ``(P, 6, N, N, C)`` (or one ``(6, N, N, C)``: ``P = 1``).

    Returns ``[(P R, 6, N_j, N_j, C)]`` float32 for ``j < ladder.levels``.  ``N`` must be
    ``ladder.sizes[0]``; inputs with NaN/Inf texels raise ``ValueError`` (as every filter).
    ``quality`` as :func:`envcap.prefilter.fast.prefilter_many` (``"composed"`` applies to the
    levels ``j >= 1``; the level-0 rungs use ``"default"`` then).  ``sky``: a ``(6, N, N, C >= 3)``
    sky cube with positive luminance: the filtered rungs' alpha (channel 3 of RGBA cubes) becomes
    :func:`sky_weighted_alpha` (rung 0 keeps the captured alpha).
    """
    a = np.asarray(cubes)
    if a.ndim == 4:
        a = a[None]
    if a.ndim != 5:
        raise ValueError(f"cubes must be (P, 6, N, N, C) or (6, N, N, C), got shape {a.shape}")
    for p in range(a.shape[0]):
        check_finite_cube(a[p], f"cube {p}")
    a = a.astype(np.float64, copy=False)
    p_all, _, n, _, nch = a.shape
    if n != ladder.sizes[0]:
        raise ValueError(f"cubes have {n}-texel faces, the rung ladder starts at {ladder.sizes[0]}")
    r_per = ladder.per_level
    out = [np.empty((p_all * r_per, 6, s, s, nch), np.float32) for s in ladder.sizes]
    own = ctx is None
    if own:
        ctx = create_context()
    try:
        level_q = quality if quality != "composed" else "default"
        for r in range(r_per):
            if ladder.levels > 1:
                powers = (ladder.powers[0],) + tuple(ladder.level_powers(j)[r] for j in range(1, ladder.levels))
                chain = prefilter_many(a, LobeLadder(ladder.sizes, powers), quality=quality, ctx=ctx, progress=progress)
                for j in range(1, ladder.levels):
                    out[j][r::r_per] = chain[j]
            for p in range(p_all):
                out[0][p * r_per + r] = a[p] if r == 0 else prefilter_level(a[p], ladder.powers[r], n, quality=level_q, ctx=ctx)
        if sky is not None:
            sky_weighted_alpha(out, a, np.asarray(sky, np.float64), ladder, quality, ctx)
    finally:
        if own:
            ctx.release()
    return out


def sky_weighted_alpha(levels: list[NDArray[np.float32]], cubes: NDArray[np.float64], sky: NDArray[np.float64],
                       ladder: RungLadder, quality: Quality = "default", ctx: Any = None) -> None:
    """Set the alpha (channel 3) of every filtered rung of ``levels`` (as returned by
    :func:`prefilter_rungs` for ``cubes`` ``(P, 6, N, N, 4)``) to ``filter(alpha Y) / filter(Y)``,
    ``Y`` the luminance of ``sky`` ``(6, N, N, C >= 3)`` (same filter); in place.  ``ValueError``
    if the cubes have no alpha or the sky has a texel of luminance <= 0 (a lobe could then see none)."""
    if cubes.shape[-1] < 4 or sky.ndim != 4 or sky.shape[-1] < 3 or sky.shape[:3] != cubes.shape[1:4]:
        raise ValueError(f"sky-weighted alpha needs RGBA cubes and an RGB sky of their size, got {cubes.shape}, {sky.shape}")
    y = luminance(sky[..., :3])
    if not np.all(y > 0):
        raise ValueError(f"sky-weighted alpha needs a sky of positive luminance, got min {float(y.min())!r}")
    weighted = prefilter_rungs(cubes[..., 3:4] * y[None, ..., None], ladder, quality, ctx)
    ysky = prefilter_rungs(y[..., None], ladder, quality, ctx)
    r_per = ladder.per_level
    for j, lv in enumerate(levels):
        p = lv.shape[0] // r_per
        alpha = weighted[j][..., 0].reshape((p, r_per) + lv.shape[1:4]) / ysky[j][..., 0][None]
        alpha = np.clip(alpha, 0.0, 1.0).reshape(lv.shape[:4])
        if j == 0:
            alpha[0::r_per] = lv[0::r_per, ..., 3]   # rung 0: the capture's own alpha
        lv[..., 3] = alpha


def rung_textures(cubes: ArrayLike, sky: ArrayLike, mode: str, quality: Quality = "default", ctx: Any = None,
                  progress: bool | None = None) -> tuple[RungLadder, list[NDArray[np.float32]], list[NDArray[np.float32]]]:
    """What a bake with a rung ladder stores (``envcap capture --ladder MODE``): ``(ladder, probes,
    sky)`` for captures ``(P, 6, N, N, 4)`` and the sky map ``(6, N, N, 4)``: ``ladder =
    rung_ladder(N, mode)``, the probes' rung levels ``[(P R, 6, N_j, N_j, 4)]`` with sky-weighted
    alpha for ``sky`` (:func:`sky_weighted_alpha`; plain filtered alpha where the sky has a texel of
    luminance <= 0, e.g. a black lat-long sky) and the sky's ``[(R, 6, N_j, N_j, 4)]``."""
    a = np.asarray(cubes)
    s = np.asarray(sky)
    if a.ndim != 5 or s.shape != a.shape[1:]:
        raise ValueError(f"rung textures need captures (P, 6, N, N, 4) and a sky (6, N, N, 4) of their size, "
                         f"got {a.shape}, {s.shape}")
    lad = rung_ladder(a.shape[2], mode)
    weighted = bool(np.all(luminance(np.asarray(s[..., :3], np.float64)) > 0))
    probes = prefilter_rungs(a, lad, quality, ctx, progress, sky=s if weighted else None)
    return lad, probes, prefilter_rungs(s, lad, quality, ctx, progress=False)
