"""Filter cubes into a rung ladder (:class:`envcap.core.rungs.RungLadder`): ``R`` cosine lobes per
mip level, as the layers of a mip-mapped cube-map array (``docs/lobes.md``, "Ladder modes").

Rung ``i = j R + r`` of probe ``p`` is layer ``p R + r`` of level ``j``: the normalized
``cos^powers[i]`` average (:mod:`envcap.prefilter.exact` defines it) on ``N_j``-texel faces.
Rung 0 is the input itself.

``quality="composed"`` (what a bake uses): the fast rung filter (``docs/lobes.md``, "Bake cost of
a rung ladder"): every rung with ``w > SH_MAX_POWER`` composed from the nearest sharper rung with
the difference lobe (:func:`rung_plan`, one run of
:func:`envcap.prefilter.composed.prefilter_many_composed` over the flat rung list), the wider ones
in spherical harmonics (:func:`envcap.prefilter.wide_lobes.filter_wide_lobes`), the hot texels
exact, the sky-weighted alpha in the same passes, float32.  Other qualities: levels ``j >= 1`` of
layer ``r`` are one chain of :func:`envcap.prefilter.fast.prefilter_many` on the ladder
``(powers[0], powers[R + r], powers[2R + r], ..)`` (its level 0, the input, is dropped); the
level-0 rungs ``r >= 1`` are filtered at full resolution by
:func:`envcap.prefilter.fast.prefilter_level`, one cube at a time.

Sky-weighted alpha (``sky=``, ``docs/lobes.md``, "Composite after filtering"): the runtime
composites after filtering, ``street_w + (1 - alpha_w) sky_w``, which misses the covariance of
alpha and the sky under the lobe.  With the alpha of every filtered rung replaced by
``filter(alpha Y) / filter(Y)`` (``Y``: the sky's luminance) the same composite is exact in
luminance for that sky, and for any uniform scaling of it; no extra texel, no runtime change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.color import luminance
from envcap.core.lobes import LobeLadder
from envcap.core.rungs import RungLadder, rung_ladder
from envcap.gpu.context import create_context
from envcap.prefilter.composed import prefilter_many_composed
from envcap.prefilter.composition import (
    COMPOSED_EPS,
    TAYLOR_MIN_SIZE,
    LevelStep,
    mean_cosine,
    power_of_mean_cosine,
)
from envcap.prefilter.exact import check_finite_cube
from envcap.prefilter.fast import Quality, prefilter_level, prefilter_many
from envcap.prefilter.footprint import LOOP_BUDGET, footprint_theta, loop_estimate
from envcap.prefilter.hot import hot_texels, luminance_weight
from envcap.prefilter.wide_lobes import SH_MAX_POWER, filter_wide_lobes

__all__ = ["FlatRungs", "rung_plan", "prefilter_rungs", "sky_weighted_alpha", "rung_textures"]

CHUNK_BYTES = 64 << 20
"""Probes per call of the fast rung filter: their level-0 RGBA float32 fits this (plus half as much
for the sky-weighted alpha)."""

TAYLOR_THETA = 0.16
"""Widest footprint cap (radians) of a rung filtered with the composed filter's quartic weights
(their log error grows as ~``w theta^6`` towards the cap's edge, where the weights are 1e-3 of the
peak; measured: the rung errors at 64^2 do not change from ``TAYLOR_MAX_THETA`` = 0.11 to 0.16)."""
MIN_SIGMA_TEXELS = 0.7
"""A rung is composed from a source rung only if the source's and the difference lobe's RMS angles
are at least this many of the source's face-centre texels ``h``: the texel-centre quadrature of a
lobe of RMS ``s`` errs by ~``exp(-2 pi^2 s^2 / h^2)`` (6e-5 at 0.7; 7e-3 at 0.5)."""

SH_SOURCE_SIGMA_TEXELS = 1.5
"""The wide rungs are projected from the last composed rung when its RMS angle spans at least this
many of its face-centre texels (at N >= 32: ``w = 43`` on 32^2 faces, 2.4 texels) and no cube has a
hot texel (a sun in a filtered rung would ring through the truncated harmonics of the ``w <= 2``
lobes: 9 % in alpha at ``w = 1``), else from the input with the hot texels exact."""


@dataclass(frozen=True)
class FlatRungs:
    """The rungs ``0 .. K`` of a :class:`~envcap.core.rungs.RungLadder` as one chain, the form the
    composed filter reads (:func:`envcap.prefilter.composed.prefilter_many_composed`): ``sizes[i]``,
    ``powers[i]`` of rung ``i`` (sizes repeat ``R`` times per level, so this is not a
    :class:`~envcap.core.lobes.LobeLadder`)."""

    sizes: tuple[int, ...]
    powers: tuple[float, ...]

    @property
    def levels(self) -> int:
        return len(self.sizes)


def _sigma(w: float) -> float:
    """Per-axis RMS angle (radians) of the normalized ``cos^w`` lobe, small-angle: ``1 / sqrt(w + 2)``."""
    return 1.0 / math.sqrt(w + 2.0)


def _step(sizes: list[int], i: int, j: int, lobe: float) -> LevelStep:
    theta = footprint_theta(lobe, COMPOSED_EPS)
    return LevelStep(i, j, lobe, sizes[j] >= TAYLOR_MIN_SIZE and theta <= TAYLOR_THETA)


def _difference(powers: list[float], sizes: list[int], i: int, j: int, n: int) -> float | None:
    """The difference lobe making rung ``i`` from rung ``j`` held on ``n``-texel faces, or ``None``
    where the quadrature on those texels would not hold (``MIN_SIGMA_TEXELS``) or the footprint is
    over the GL loop budget."""
    rd = mean_cosine(powers[i]) / mean_cosine(powers[j])
    if not 0.5 < rd < 1.0:
        return None
    wd = power_of_mean_cosine(rd)
    texel = 2.0 / n
    if min(_sigma(wd), _sigma(powers[j])) < MIN_SIGMA_TEXELS * texel:
        return None
    if loop_estimate(footprint_theta(wd, COMPOSED_EPS), n) > LOOP_BUDGET:
        return None
    return wd


def rung_plan(flat: FlatRungs) -> tuple[FlatRungs, list[LevelStep]]:
    """How the fast filter makes rungs ``1 .. K`` of ``flat``: ``(chain, steps)``, ``chain`` = ``flat``
    plus the coarse copies the steps use (after index ``K``), ``steps`` in the order they run.

    Rung ``i`` is made from the nearest sharper rung ``j >= 1`` whose texels and difference lobe
    ``r(w_d) = r(w_i) / r(w_j)`` (``r``: mean cosine) make a good quadrature (both lobes at least
    ``MIN_SIGMA_TEXELS`` texels RMS), else directly from the input.  Half an octave of ``w + 2``
    apart, the difference lobe is ~0.54 of the rung's RMS angle: a small footprint.  Where ``j``
    sits on larger faces than ``i`` and is smooth enough on ``i``'s, a copy of ``j`` on ``i``'s faces
    (made by ``j``'s own step) is the source: a quarter of the footprint.  ``docs/lobes.md``, "Bake
    cost of a rung ladder", gives the error of the composition (these lobes have ``w > SH_MAX_POWER``).
    """
    sizes, powers = list(flat.sizes), [float(w) for w in flat.powers]
    steps: list[LevelStep] = []
    made: dict[int, LevelStep] = {}
    for i in range(1, flat.levels):
        chosen = _step(sizes, i, 0, powers[i])
        for j in range(i - 1, 0, -1):
            wd = _difference(powers, sizes, i, j, sizes[j])
            if wd is None:
                continue
            chosen = _step(sizes, i, j, wd)
            wd_c = _difference(powers, sizes, i, j, sizes[i]) if sizes[j] > sizes[i] else None
            if wd_c is not None:
                sizes.append(sizes[i])
                powers.append(powers[j])
                c = len(sizes) - 1
                steps.append(_step(sizes, c, made[j].source, made[j].lobe))
                chosen = _step(sizes, i, c, wd_c)
            break
        made[i] = chosen
        steps.append(chosen)
    return FlatRungs(tuple(sizes), tuple(powers)), steps


def prefilter_rungs(cubes: ArrayLike, ladder: RungLadder, quality: Quality = "default", ctx: Any = None,
                    progress: bool | None = None, sky: ArrayLike | None = None) -> list[NDArray[np.float32]]:
    """The rung levels of ``P`` cubes ``(P, 6, N, N, C)`` (or one ``(6, N, N, C)``: ``P = 1``).

    Returns ``[(P R, 6, N_j, N_j, C)]`` float32 for ``j < ladder.levels``.  ``N`` must be
    ``ladder.sizes[0]``; inputs with NaN/Inf texels raise ``ValueError`` (as every filter).
    ``quality`` as :func:`envcap.prefilter.fast.prefilter_many`; ``"composed"``: the fast rung
    filter (module docstring; RGBA cubes when ``sky`` is given).  ``sky``: a ``(6, N, N, C >= 3)``
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
    if quality == "composed":
        if sky is None:
            return _fast_rungs(a, ladder, ctx, progress, None, False)[0]
        s = np.asarray(sky, np.float64)
        _sky_luminance(a, s)
        sky4 = np.concatenate([s[..., :3], np.ones(s.shape[:3] + (1,))], -1)
        return _fast_rungs(a, ladder, ctx, progress, sky4, True)[0]
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
    if quality == "composed":
        for p in range(a.shape[0]):
            check_finite_cube(a[p], f"cube {p}")
        check_finite_cube(s, "sky")
        probes, sky_rungs = _fast_rungs(a, lad, ctx, progress, s, weighted)
        assert sky_rungs is not None
        return lad, probes, sky_rungs
    probes = prefilter_rungs(a, lad, quality, ctx, progress, sky=s if weighted else None)
    return lad, probes, prefilter_rungs(s, lad, quality, ctx, progress=False)


def _sky_luminance(cubes: NDArray, sky: NDArray[np.float64]) -> NDArray[np.float32]:
    """``Y`` ``(6, N, N)`` of ``sky`` for the sky-weighted alpha of RGBA ``cubes``; the checks of
    :func:`sky_weighted_alpha`."""
    if cubes.shape[-1] != 4 or sky.ndim != 4 or sky.shape[-1] < 3 or sky.shape[:3] != cubes.shape[1:4]:
        raise ValueError(f"sky-weighted alpha needs RGBA cubes and an RGB sky of their size, got {cubes.shape}, {sky.shape}")
    y = luminance(sky[..., :3])
    if not np.all(y > 0):
        raise ValueError(f"sky-weighted alpha needs a sky of positive luminance, got min {float(y.min())!r}")
    return y.astype(np.float32)


def _ratio(num: NDArray, den: NDArray) -> NDArray:
    """``num / den`` where ``den > 0``, else 0 (a sky-weighted alpha where the filtered sky's
    luminance is 0: no sky seen, nothing to weight)."""
    out = np.zeros(np.broadcast(num, den).shape, np.result_type(num, den))
    return np.divide(num, den, out=out, where=den > 0)


def _fast_rungs(a: NDArray, ladder: RungLadder, ctx: Any, progress: bool | None, sky: NDArray | None,
                weighted: bool) -> tuple[list[NDArray[np.float32]], list[NDArray[np.float32]] | None]:
    """The rung levels of checked cubes ``a`` ``(P, 6, N, N, C)`` (and of the RGBA ``sky`` ``(6, N, N,
    4)`` when given) by the fast filter (``docs/lobes.md``, "Bake cost of a rung ladder"): rungs with
    ``w > SH_MAX_POWER`` composed one from another on the GL context (:func:`rung_plan`), the wider
    ones in spherical harmonics from the last composed rung
    (:func:`envcap.prefilter.wide_lobes.filter_wide_lobes`), the hot texels exact.

    ``weighted``: every filtered rung's alpha becomes ``filter(alpha Y) / filter(Y)`` (``Y``: the
    sky's luminance), filtered with the probes in the same passes: ``alpha Y`` replaces a probe's
    alpha channel and ``filter(Y)`` is the luminance of the sky's rung, when the sky has no hot
    texel (both then see the same weights); else ``alpha Y`` of two probes and ``Y`` are the RGB of
    one more cube (the hot texels split from both alike).  float32 (the GL filter's precision); the
    wide rungs in float64."""
    p_all, _, n, _, nch = a.shape
    if n != ladder.sizes[0]:
        raise ValueError(f"cubes have {n}-texel faces, the rung ladder starts at {ladder.sizes[0]}")
    if p_all < 1:
        raise ValueError("cubes must hold at least one cube (P >= 1)")
    if sky is not None and nch != 4:
        raise ValueError(f"sky-weighted alpha and the sky's rungs need RGBA cubes, got {nch} channels")
    y_sky = None
    compact = False
    if weighted and sky is not None:
        y_sky = luminance(np.asarray(sky[..., :3], np.float64)).astype(np.float32)
        compact = hot_texels(luminance_weight(np.asarray(sky, np.float64)))[0].size == 0
    r_per = ladder.per_level
    sizes = tuple(s for s in ladder.sizes for _ in range(r_per))
    k = next((i - 1 for i in range(1, ladder.rungs) if ladder.powers[i] <= SH_MAX_POWER), ladder.rungs - 1)
    flat, plan = rung_plan(FlatRungs(sizes[:k + 1], tuple(ladder.powers[:k + 1])))
    out = [np.empty((p_all * r_per, 6, s, s, nch), np.float32) for s in ladder.sizes]
    sky_out = None if sky is None else [np.empty((r_per, 6, s, s, nch), np.float32) for s in ladder.sizes]
    own = ctx is None
    if own:
        ctx = create_context()
    try:
        per = max(1, int(CHUNK_BYTES // (6 * n * n * 16)))
        for b0 in range(0, p_all, per):
            q = min(per, p_all - b0)
            probes = np.array(a[b0:b0 + q], np.float32)
            members = [probes]
            h = 0
            if y_sky is not None and compact:
                probes[..., 3] *= y_sky
            elif y_sky is not None:
                h = (q + 1) // 2
                aux = np.zeros((h, 6, n, n, 4), np.float32)
                aux[..., 0] = probes[0::2, ..., 3] * y_sky
                aux[:q // 2, ..., 1] = probes[1::2, ..., 3] * y_sky
                aux[..., 2] = y_sky
                members.append(aux)
            if sky is not None:   # every chunk: the sky's weights are those of the probes' alpha Y
                members.append(np.asarray(sky, np.float32)[None])
            stack = np.concatenate(members) if len(members) > 1 else probes
            chain = prefilter_many_composed(stack, flat, ctx, progress, plan=plan)  # type: ignore[arg-type]
            wide: list[NDArray[np.float32]] = []
            if k + 1 < ladder.rungs:   # from rung k where it is smooth on its texels and has no hot texel, else from the input
                smooth = k >= 1 and _sigma(ladder.powers[k]) >= SH_SOURCE_SIGMA_TEXELS * 2.0 / sizes[k] and \
                    not any(hot_texels(luminance_weight(np.asarray(c, np.float64)))[0].size for c in stack)
                wide = filter_wide_lobes(chain[k] if smooth else stack, ladder.powers[k + 1:], sizes[k + 1:],
                                         source_power=float(ladder.powers[k]) if smooth else 0.0)
            for i, rung in enumerate(chain[:k + 1] + wide):
                j, r = divmod(i, r_per)
                dest = out[j][b0 * r_per + r:(b0 + q) * r_per:r_per]
                dest[:] = rung[:q]
                if i == 0:
                    dest[..., 3] = a[b0:b0 + q, ..., 3]
                elif compact:
                    dest[..., 3] = np.clip(_ratio(rung[:q, ..., 3], luminance(rung[-1, ..., :3])[None]), 0.0, 1.0)
                elif y_sky is not None:
                    ay = rung[q:q + h]
                    num = np.stack([ay[..., 0], ay[..., 1]], 1).reshape((2 * h,) + ay.shape[1:4])[:q]
                    dest[..., 3] = np.clip(_ratio(num, np.repeat(ay[..., 2], 2, axis=0)[:q]), 0.0, 1.0)
                if sky_out is not None and b0 == 0:
                    sky_out[j][r] = rung[-1]
                    np.clip(sky_out[j][r][..., 3], 0.0, 1.0, out=sky_out[j][r][..., 3])
    finally:
        if own:
            ctx.release()
    return out, sky_out
