"""Lookup of a rung ladder (numpy twin of ``envcap_rung_lod_of_w`` / ``envcap_rung_lod`` /
``envcap_rung_fetch`` in ``shaders/runtime/envcap_lobes.glsl``): the cos^w-convolved environment
of one probe from a mip-mapped cube-map array holding ``R`` rungs per level
(:mod:`envcap.core.rungs`).

Layer ``base + r`` at level ``j`` holds rung ``i = j R + r``.  A lookup of power ``w`` takes its
*lookup position* ``u`` (:func:`rung_lod_of_w`): the continuous rung position (piecewise linear
in ``log2(1 + w)`` over the rung table ``xr``, at most ``n - 1``; ``w < 0`` and NaN count as 0,
as in GLSL) and, above rung 0's power, the top segment ``u = -(1 - (1 + w_0) / (1 + w))`` in
``(-1, 0)`` (``+inf``: -1, the mirror).  :func:`rung_lod` blends rungs ``i0 = floor(u)`` and
``i0 + 1`` linearly in ``u``, each one seamless bilinear fetch at its integer level
(:mod:`envcap.core.cube_sampling`), except rung 0, the capture, which is read with the lobe's own
2x2 footprint kernel at its power (``u <= 0``: at the power ``u`` encodes;
:mod:`envcap.runtime.rung_top`, ``docs/lobes.md`` "The top of the ladder").  Float64;
``dtype=np.float32`` evaluates positions in float32 in the GLSL order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube_sampling
from envcap.core.rungs import RungLadder, rung_ladder
from envcap.prefilter.rungs import prefilter_rungs
from envcap.runtime.rung_top import top_fetch, top_power
from envcap.probeset.probe_set import ProbeSet
from envcap.runtime.mip import lobe_table, z_of_w

__all__ = ["MAX_RUNGS", "RungChains", "rung_table", "rung_position", "rung_lod_of_w", "rung_lod", "rung_fetch",
           "rung_chains_of", "rung_street_uniforms"]

MAX_RUNGS = 48
"""Most rungs of a rung table (length of the GLSL ``xr`` array).  GLSL ``#define ENVCAP_MAX_RUNGS``."""


def rung_table(powers: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """``xr_i = log2(1 + powers[i])`` for the GLSL uniform ``xr``: :func:`envcap.runtime.mip.lobe_table`
    with room for :data:`MAX_RUNGS` powers (strictly decreasing, finite, >= 0; else ``ValueError``)."""
    return lobe_table(powers, dtype, most=MAX_RUNGS)


def rung_position(w: ArrayLike, xr: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Continuous rung position of power(s) ``w`` on the table ``xr``: the same rule as a mip level
    (:func:`envcap.runtime.mip.z_of_w`, the GLSL loop; never raises)."""
    return z_of_w(w, xr, dtype)


def rung_lod_of_w(w: ArrayLike, xr: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Lookup position of power(s) ``w`` on the table ``xr`` (GLSL ``envcap_rung_lod_of_w``, never
    raises): :func:`rung_position` up to rung 0's power ``w_0``, above it the top segment
    ``-(1 - 2^(xr[0] - log2(1 + w)))`` in ``(-1, 0)``; ``+inf`` gives -1 (the mirror)."""
    xr = np.asarray(xr, dtype=dtype)
    w = np.asarray(w, dtype=dtype)
    u = np.asarray(rung_position(w, xr, dtype), dtype=dtype)
    with np.errstate(invalid="ignore", over="ignore"):
        x = np.log2(dtype(1.0) + np.where(w > 0, w, dtype(0.0)))
    top = ~(x < xr[0]) & ~np.isnan(x)
    u[top] = -(dtype(1.0) - np.exp2(xr[0] - x[top]))
    return u


def rung_lod(levels: Sequence[ArrayLike], d: ArrayLike, base: ArrayLike, u: ArrayLike,
             per_level: int) -> NDArray[np.float64]:
    """``(..., C)`` at lookup position ``u`` (GLSL ``envcap_rung_lod``; ``u`` clamped to ``>= -1``,
    NaN -> 0, at most the last rung): rungs ``floor(u)`` and the next of the cube-map array
    ``levels`` (``[j]``: ``(layers, 6, N_j, N_j, C)``) along unit ``d`` ``(..., 3)`` at layers
    ``base + i % per_level``, levels ``i // per_level``, blended linearly in ``u``; rung 0 is
    :func:`envcap.runtime.rung_top.top_fetch` at :func:`envcap.runtime.rung_top.top_power` of
    ``min(u, 0)`` (its own power for ``0 <= u < 1``)."""
    if int(per_level) < 1:
        raise ValueError(f"per_level must be >= 1, got {per_level}")
    r = int(per_level)
    d = np.asarray(d, dtype=np.float64)
    shape = d.shape[:-1]
    u = np.asarray(np.broadcast_to(np.asarray(u, np.float64), shape))
    u = np.where(u > -1.0, u, np.where(u <= -1.0, -1.0, 0.0))
    b = np.broadcast_to(np.asarray(base, dtype=np.float64), shape)
    up = np.maximum(u, 0.0)
    i0 = np.floor(up).astype(np.int64)
    i1 = i0 + 1
    t = (up - i0)[..., None]
    a = np.zeros(shape + (np.asarray(levels[0]).shape[-1],))
    top = i0 == 0
    if np.any(top):
        n0 = np.asarray(levels[0]).shape[-2]
        layer0 = np.clip(np.floor(b[top] + 0.5), 0, np.asarray(levels[0]).shape[0] - 1).astype(np.int64)
        a[top] = top_fetch(levels[0], d[top], layer0, top_power(u[top], n0))
    if np.any(~top):
        a[~top] = cube_sampling.sample_cube_array(levels, d[~top], b[~top] + (i0[~top] % r), (i0[~top] // r).astype(np.float64))
    out = a.copy()
    two = t[..., 0] > 0
    if np.any(two):
        c = cube_sampling.sample_cube_array(levels, d[two], b[two] + (i1[two] % r), (i1[two] // r).astype(np.float64))
        out[two] = a[two] + t[two] * (c - a[two])
    return out


def rung_fetch(levels: Sequence[ArrayLike], d: ArrayLike, base: ArrayLike, w: ArrayLike, xr: ArrayLike,
               per_level: int) -> NDArray[np.float64]:
    """``(..., C)``: :func:`rung_lod` at the lookup position ``rung_lod_of_w(w, xr)`` of power(s)
    ``w`` (GLSL ``envcap_rung_fetch``); ``levels`` must hold the table's rungs."""
    if int(per_level) < 1:
        raise ValueError(f"per_level must be >= 1, got {per_level}")
    n = np.asarray(xr).size
    if len(levels) * int(per_level) < n:
        raise ValueError(f"{len(levels)} levels x {per_level} rungs hold fewer than the table's {n} rungs")
    d = np.asarray(d, dtype=np.float64)
    u = np.broadcast_to(rung_lod_of_w(w, xr), d.shape[:-1])
    return rung_lod(levels, d, base, u, per_level)


@dataclass(frozen=True)
class RungChains:
    """Rung-ladder textures of ``P`` probes: ``levels[j]`` ``(P R, 6, N_j, N_j, C)`` (layer
    ``p R + r``), the ladder, and its table ``xr``.  Every texel finite (checked when built)."""

    levels: Sequence[NDArray]
    ladder: RungLadder

    def __post_init__(self) -> None:
        lv = [np.asarray(a) for a in self.levels]
        object.__setattr__(self, "levels", lv)
        if len(lv) != self.ladder.levels:
            raise ValueError(f"rung chains need {self.ladder.levels} levels, got {len(lv)}")
        for j, a in enumerate(lv):
            s = self.ladder.sizes[j]
            if a.ndim != 5 or a.shape[1:4] != (6, s, s) or a.shape[0] % self.ladder.per_level or a.shape[0] != lv[0].shape[0]:
                raise ValueError(f"rung level {j} must be (P*{self.ladder.per_level}, 6, {s}, {s}, C), got {a.shape}")
            if a.dtype.kind == "f" and not np.isfinite(a).all():
                raise ValueError(f"rung level {j}: {int((~np.isfinite(a)).sum())} texel values are NaN/Inf")

    @property
    def xr(self) -> NDArray[np.float64]:
        return rung_table(self.ladder.powers)

    def fetch(self, d: ArrayLike, probe: ArrayLike, w: ArrayLike) -> NDArray[np.float64]:
        """``(..., C)`` of probe index ``probe`` along unit ``d`` for lobe power ``w``."""
        base = np.asarray(probe, dtype=np.float64) * self.ladder.per_level
        return rung_fetch(self.levels, d, base, w, self.xr, self.ladder.per_level)


def rung_chains_of(probe_set: ProbeSet, mode: str = "half_octave", quality: str = "default",
                   ctx: Any = None, sky_alpha: bool = True) -> tuple[RungChains, RungChains]:
    """``(probes, sky)``: the rung textures of ``probe_set``'s captures (its level 0) and of its sky
    map (level 0), filtered with :func:`envcap.prefilter.rungs.prefilter_rungs` on
    ``rung_ladder(N, mode)`` (the sky as one probe: rungs at layers 0..R-1).  ``sky_alpha``: the
    probes' filtered alpha sky-weighted for the set's sky map (the composite after filtering is
    then exact for it, :func:`envcap.prefilter.rungs.sky_weighted_alpha`).  The sky map must have
    the probes' face size."""
    n = probe_set.resolution
    lad = rung_ladder(n, mode)
    sky0 = np.asarray(probe_set.sky_levels[0], np.float64)
    if sky0.shape[1] != n:
        raise ValueError(f"sky map has {sky0.shape[1]}-texel faces, the probes {n}: rung ladders need one size")
    probes = prefilter_rungs(np.asarray(probe_set.levels[0], np.float64), lad, quality=quality, ctx=ctx,  # type: ignore[arg-type]
                             sky=sky0 if sky_alpha else None)
    sky = prefilter_rungs(sky0, lad, quality=quality, ctx=ctx)  # type: ignore[arg-type]
    return RungChains(probes, lad), RungChains(sky, lad)


def rung_street_uniforms(uniforms: Any, ladder: RungLadder, uniform: str = "envcap_street") -> dict[str, Any]:
    """The values of a street's ``EnvcapStreet`` uniform for the rung street variant
    (``shaders/runtime/envcap_rung_street.glsl``): ``uniforms.values(uniform)`` (a
    :class:`envcap.runtime.street.StreetUniforms`, any lobe table) with ``xk`` the rung table of
    ``ladder`` padded to :data:`MAX_RUNGS` (the variant's ``ENVCAP_MAX_LEVELS``) and ``nlevels`` its
    number of rungs.  ``pos[i].w`` stays probe ``i``'s index (the variant multiplies it by ``R``)."""
    values = dict(uniforms.values(uniform))
    xr = np.zeros(MAX_RUNGS, np.float32)
    xr[:ladder.rungs] = rung_table(ladder.powers, np.float32)
    values[f"{uniform}.xk"] = xr
    values[f"{uniform}.nlevels"] = int(ladder.rungs)
    return values
