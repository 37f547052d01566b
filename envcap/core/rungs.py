"""Ladder modes: the paper's single chain, or a *rung ladder* that holds between levels and at
wide lobes (``docs/lobes.md``, "Ladder modes").

A rung ladder stores ``R`` lobes ("rungs") per mip level instead of one: a mip-mapped cube-map
array whose layer ``p R + r`` at level ``j`` (faces of ``N_j = N >> j`` texels) holds probe
``p`` convolved with the normalized ``cos^w`` lobe of rung ``i = j R + r``.  Rungs are ordered by
strictly decreasing power (flat index ``i``); rung 0 is the unfiltered capture.  The chain stops
at faces of ``min_face`` texels (8 by default): the wide lobes (``w <= 16``) live on 8^2 and 16^2
faces, where a level holds its lobe with an RMS angle of about 2 texels, instead of 4^2..1^2.

Rung powers (``v = w + 2``, the inverse per-axis variance of the lobe, ``docs/lobes.md``):

* levels ``1 <= j < J - 1``: ``v = (N_j / (2 s))^2 4^(-r / R)``: lobes of RMS angle ``s`` to
  ``2 s`` texels (``s = sigma_texels``, sqrt 2 by default), ``R`` rungs per two octaves of ``v``
  (``R = 4``: half an octave of ``w + 2`` between rungs);
* level 0: the capture (``v = 3 N^2``), then ``R - 1`` rungs geometric in ``v`` down to level
  1's first rung (these lobes are narrower than ``s`` texels: the capture's resolution bounds them);
* the last level: ``R`` rungs geometric in ``v`` from ``(N_{J-1} / (2 s))^2`` down to
  ``w_min + 2`` (the widest lobe, ``w_min = 1``: the diffuse term of Eq. 3).

A lookup of power ``w`` finds its continuous rung position ``u`` (piecewise linear in
``log2(1 + w)`` over the rung powers, as the paper's ``z(w)`` over levels) and blends rungs
``floor(u)`` and ``floor(u) + 1`` (two bilinear fetches at integer levels: the texel reads of one
trilinear fetch).  Runtime twin: :mod:`envcap.runtime.rungs`; GLSL ``envcap_rung_fetch``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.lobes import lobe_ladder, texel_power, z_of_w

__all__ = ["LADDER_MODES", "LadderMode", "RUNG_RULE", "RungLadder", "rung_ladder", "ladder_bytes_per_probe"]

LadderMode = Literal["paper", "half_octave", "octave"]
"""``"paper"``: one lobe per level, two octaves of ``1 + w`` apart, down to 1^2 faces (the paper's
single chain, the default); ``"half_octave"``: 4 rungs per level (half an octave of ``w + 2``
apart), down to 8^2 faces; ``"octave"``: 2 rungs per level (one octave apart), down to 8^2."""
LADDER_MODES: tuple[str, ...] = get_args(LadderMode)
RUNGS_PER_LEVEL = {"half_octave": 4, "octave": 2}
RUNG_RULE = "rungs: piecewise-linear in log2(1+w) over flat rung powers; rung i = (level i // R, layer i % R)"


@dataclass(frozen=True)
class RungLadder:
    """Face sizes of the ``J`` levels and the ``J R`` rung powers (flat, strictly decreasing).

    ``sizes[j] = N_0 >> j``; ``powers[i]`` is the normalized cosine power of rung ``i`` at level
    ``i // per_level``, layer ``i % per_level`` of each probe; ``powers[0]`` is the capture's
    texel power (rung 0 is unfiltered).
    """

    sizes: tuple[int, ...]
    powers: tuple[float, ...]
    per_level: int

    def __post_init__(self) -> None:
        if self.per_level < 1 or not self.sizes or len(self.powers) != len(self.sizes) * self.per_level:
            raise ValueError(f"RungLadder needs per_level >= 1 and len(sizes) * per_level powers, got "
                             f"{len(self.sizes)} sizes, {len(self.powers)} powers, per_level {self.per_level}")
        for j, s in enumerate(self.sizes):
            if s != max(self.sizes[0] >> j, 1):
                raise ValueError(f"RungLadder sizes must be N_0 >> j, got {self.sizes}")
        p = np.asarray(self.powers, dtype=np.float64)
        if not np.all(np.isfinite(p)) or np.any(p < 0) or np.any(np.diff(p) >= 0):
            raise ValueError(f"RungLadder powers must be finite, >= 0 and strictly decreasing, got {self.powers}")

    @property
    def levels(self) -> int:
        return len(self.sizes)

    @property
    def rungs(self) -> int:
        return len(self.powers)

    def level_powers(self, j: int) -> tuple[float, ...]:
        """The ``per_level`` powers of level ``j`` (layer order)."""
        return self.powers[j * self.per_level:(j + 1) * self.per_level]

    def position(self, w: ArrayLike) -> NDArray[np.float64]:
        """Continuous rung position ``u`` in ``[0, rungs - 1]`` for power(s) ``w`` (float64, shape of
        ``w``); the rule of :func:`envcap.core.lobes.z_of_w` over the flat rung table (raises
        ``ValueError`` for negative or NaN ``w``)."""
        return z_of_w(w, self.powers)

    def bytes_per_probe(self, bytes_per_texel: int = 8) -> int:
        """Texture bytes one probe takes (``per_level`` layers at every level; rgba16f: 8 B/texel)."""
        return int(self.per_level * sum(6 * s * s for s in self.sizes) * bytes_per_texel)

    def to_manifest(self) -> dict[str, Any]:
        """JSON-ready table ``{"sizes", "powers", "per_level", "rule"}``."""
        return {"sizes": [int(s) for s in self.sizes], "powers": [float(p) for p in self.powers],
                "per_level": int(self.per_level), "rule": RUNG_RULE}

    @staticmethod
    def from_manifest(m: dict[str, Any]) -> "RungLadder":
        """Inverse of :meth:`to_manifest` (``ValueError``/``KeyError`` on a bad table)."""
        if m.get("rule", RUNG_RULE) != RUNG_RULE:
            raise ValueError(f"unknown rung rule {m.get('rule')!r}")
        return RungLadder(tuple(int(s) for s in m["sizes"]), tuple(float(p) for p in m["powers"]), int(m["per_level"]))


def _geometric(v0: float, v1: float, count: int, include_end: bool) -> list[float]:
    """``count`` values geometric from ``v0`` towards ``v1`` (ending at ``v1`` when ``include_end``)."""
    steps = count - 1 if include_end else count
    if steps <= 0:
        return [v0]
    return [v0 * (v1 / v0) ** (r / steps) for r in range(count)]


def rung_ladder(n: int, mode: str = "half_octave", sigma_texels: float = math.sqrt(2.0), min_face: int = 8,
                w_min: float = 1.0) -> RungLadder:
    """The rung ladder of ``mode`` (``"half_octave"`` or ``"octave"``) for ``n``-texel faces.

    Levels down to faces of ``min_face`` texels (all of them when ``n < min_face``); powers as in
    the module docstring; ``ValueError`` for a bad size or mode.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"face size must be a positive integer, got {n!r}")
    if mode not in RUNGS_PER_LEVEL:
        raise ValueError(f"rung ladder mode must be one of {sorted(RUNGS_PER_LEVEL)}, got {mode!r}")
    if not (sigma_texels > 0 and math.isfinite(sigma_texels)) or not (w_min >= 0 and math.isfinite(w_min)):
        raise ValueError(f"sigma_texels must be > 0 and w_min >= 0, got {sigma_texels}, {w_min}")
    n = int(n)
    r_per = RUNGS_PER_LEVEL[mode]
    sizes = [n]
    while sizes[-1] // 2 >= min(min_face, n) and sizes[-1] > 1:
        sizes.append(sizes[-1] // 2)
    levels = len(sizes)
    v_top = texel_power(n) + 2.0
    v_min = w_min + 2.0

    def v_first(j: int) -> float:
        return (sizes[j] / (2.0 * sigma_texels)) ** 2

    v: list[float] = []
    for j in range(levels):
        if levels == 1:
            v += _geometric(v_top, v_min, r_per, include_end=True)
        elif j == 0:
            v += _geometric(v_top, v_first(1), r_per, include_end=False)
        elif j == levels - 1:
            v += _geometric(max(v_first(j), v_min * 1.01), v_min, r_per, include_end=True)
        else:
            v += _geometric(v_first(j), v_first(j) / 4.0, r_per, include_end=False)
    w = [x - 2.0 for x in v]
    for i in range(len(w) - 2, -1, -1):   # tiny faces: keep strictly decreasing
        if w[i] <= w[i + 1]:
            w[i] = 2.0 * (1.0 + w[i + 1]) - 1.0
    return RungLadder(tuple(sizes), tuple(float(x) for x in w), r_per)


def ladder_bytes_per_probe(mode: str, n: int, bytes_per_texel: int = 8) -> int:
    """Texture bytes per probe of ladder ``mode`` at face size ``n`` (rgba16f: 8 B per texel).

    ``"paper"``: the full chain ``N, N/2, .., 1`` (:func:`envcap.core.lobes.lobe_ladder`).
    """
    if mode == "paper":
        return int(sum(6 * s * s for s in lobe_ladder(n).sizes) * bytes_per_texel)
    return rung_ladder(n, mode).bytes_per_probe(bytes_per_texel)
