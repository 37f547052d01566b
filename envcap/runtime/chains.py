"""A probe set's textures as the numpy twin samples them: the probes' cosine-lobe chains (a
cube-map array per level), the lobe table, the optional distance channel, and the sky chain.

Texture lookups go through :mod:`envcap.core.cube_sampling` (the GL sampler's twin: seamless
trilinear).  Conventions: cubes ``(6, N, N, C)`` (``envcap/core/cube.py``); premultiplied RGBA.

Textures are checked when built (:class:`ProbeChains`, :class:`SkyChain`): every texel finite,
else one-line ``ValueError`` naming the level and the layer.  The GLSL runtime cannot raise: a
NaN texel there is NaN light, so textures are checked where they are read or built
(``envcap.probeset.store.read_probe_set`` checks the files, these classes the arrays).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube_sampling
from envcap.core.rungs import RungLadder
from envcap.probeset.probe_set import ProbeSet
from envcap.runtime.mip import level_of_power, lobe_table
from envcap.runtime.rungs import rung_fetch, rung_position, rung_table


def check_finite_levels(levels: Sequence[ArrayLike], what: str, layered: bool) -> None:
    """``ValueError`` (one line naming ``what``, the level and the layer) if a texel of ``levels``
    is NaN or Inf.  ``layered``: levels are ``(L, 6, N, N, C)`` cube arrays (``L`` layers), else
    ``(6, N, N, C)`` cubes."""
    for k, level in enumerate(levels):
        a = np.asarray(level)
        if a.dtype.kind not in "fc" or bool(np.isfinite(a).all()):
            continue
        bad = ~np.isfinite(a).reshape((a.shape[0], -1) if layered else (1, -1))
        per_layer = bad.sum(axis=1)
        layer = int(np.flatnonzero(per_layer)[0])
        where = f"level {k}, layer {layer}" if layered else f"level {k}"
        rest = f" ({int(per_layer.sum())} in all, in {int(np.count_nonzero(per_layer))} layer(s))" if layered else ""
        raise ValueError(f"{what} {where}: {int(per_layer[layer])} of {bad.shape[1]} texel values are NaN/Inf{rest}; "
                         "the runtime would turn them into NaN light")


@dataclass(frozen=True)
class SkyChain:
    """The sky's cosine-lobe chain: ``levels[k]`` ``(6, M_k, M_k, C)`` convolved with the
    normalized cos^powers[k] lobe of the probes' ladder (no lobe table of its own); every texel
    finite (checked when built).  ``ladder``: the sky of a rung-ladder set, ``levels[j]``
    ``(R, 6, M_j, M_j, C)``, layer ``r`` = rung ``j R + r`` (looked up by ``envcap_rung_fetch``)."""

    levels: Sequence[NDArray]
    ladder: RungLadder | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "levels", [np.asarray(a) for a in self.levels])
        if not self.levels:
            raise ValueError("sky chain has no levels")
        check_finite_levels(self.levels, "sky chain", layered=self.ladder is not None)

    @staticmethod
    def of(sky: "SkyChain | Sequence[ArrayLike]") -> "SkyChain":
        """``sky`` as a :class:`SkyChain` (a sequence of levels is checked; a chain is returned as is)."""
        return sky if isinstance(sky, SkyChain) else SkyChain(sky)


@dataclass(frozen=True)
class ProbeChains:
    """``levels[k]``: ``(L, 6, N_k, N_k, 4)`` premultiplied street RGBA of the ``L`` probes (cube-array
    layers) convolved with the normalized cos^powers[k] lobe; ``powers``: the strictly decreasing
    lobe table (one power per level); ``distance``: ``(L, 6, N, N)`` radial distance (m) from each
    probe to what it sees, 0 where the sky shows, or ``None`` (stored as float64).  Every texel of
    ``levels`` is finite (checked when built: ``ValueError`` naming the level and the layer).
    ``ladder``: a rung ladder (:mod:`envcap.runtime.rungs`, ``docs/lobes.md``): ``levels[j]`` then
    holds ``R = ladder.per_level`` layers per probe (layer ``p R + r``: rung ``j R + r``),
    ``powers`` is the flat rung table ``ladder.powers``, ``xk`` its table and :meth:`level` the
    continuous rung position; :meth:`fetch` blends two rungs (``envcap_rung_fetch``)."""

    levels: Sequence[NDArray]
    powers: NDArray[np.float64]
    distance: NDArray[np.float64] | None = None
    ladder: RungLadder | None = None
    xk: NDArray[np.float64] = field(init=False, repr=False)
    """``lobe_table(powers)``: the z(w) table (``rung_table(powers)`` for a rung ladder)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "powers", np.asarray(self.powers, np.float64))
        want = len(self.levels) if self.ladder is None else self.ladder.rungs
        if self.powers.shape != (want,) or (self.ladder is not None and (len(self.levels) != self.ladder.levels or not
                                                                         np.array_equal(self.powers, self.ladder.powers))):
            raise ValueError(f"need one lobe power per level (per rung of a ladder): {len(self.levels)} levels, "
                             f"powers {self.powers.shape}")
        check_finite_levels(self.levels, "probe chain", layered=True)
        if self.distance is not None:
            object.__setattr__(self, "distance", np.asarray(self.distance, np.float64))
        object.__setattr__(self, "xk", lobe_table(self.powers) if self.ladder is None else rung_table(self.powers))

    @staticmethod
    def from_probe_set(probe_set: ProbeSet) -> "ProbeChains":
        """The chains of a probe set (its ``levels``, the manifest's lobe powers, its ``distance``;
        a set baked with a rung ladder: its ``rungs`` and ``manifest.ladder``)."""
        if probe_set.manifest.ladder is not None and probe_set.rungs is not None:
            lad = probe_set.manifest.ladder.rung_ladder()
            return ProbeChains([np.asarray(a) for a in probe_set.rungs], np.array(lad.powers), probe_set.distance, lad)
        levels = [np.asarray(a) for a in probe_set.levels]
        powers = probe_set.manifest.lobe_powers
        if powers is None or len(powers) != len(levels):
            raise ValueError("probe set has no lobe ladder (baked without filtered levels): cannot evaluate lobes")
        return ProbeChains(levels, np.array([float(p) for p in powers]), probe_set.distance)

    def level(self, w: ArrayLike) -> NDArray[np.float64]:
        """The clamped continuous level a lookup of lobe power ``w`` samples (rung ladder: its rung position)."""
        return level_of_power(w, self.xk) if self.ladder is None else rung_position(w, self.xk)

    def fetch(self, r: ArrayLike, layer: ArrayLike, w: ArrayLike) -> NDArray[np.float64]:
        """RGBA ``(..., 4)`` of probe ``layer`` along unit ``r`` ``(..., 3)`` at the level of power ``w``."""
        if self.ladder is not None:
            per = self.ladder.per_level
            return rung_fetch(self.levels, r, np.asarray(layer, np.float64) * per, w, self.xk, per)
        return cube_sampling.sample_cube_array(self.levels, r, layer, self.level(w))
