"""The lobe ladder: which normalized cosine power ``w_k`` mip level ``k`` holds, and ``z(w)``.

Level ``k`` of a chain (face size ``N_k = N_0 >> k``) holds the environment convolved with the
*normalized* lobe ``max(0, d.u)^w_k / (2 pi / (w_k + 1))`` (a solid-angle weighted average over
the sphere).  Level 0 is the unfiltered capture; ``powers[0]`` is the cosine power whose lobe has
the angular variance of one level-0 texel at a face center.  Derivation: ``docs/lobes.md``.

The runtime looks up a power ``w`` at the continuous level ``z(w)``: piecewise-linear
interpolation of the level index ``k`` over ``x = log2(1 + w)`` at the nodes
``x_k = log2(1 + powers[k])`` (clamped to ``[0, L - 1]``), then trilinear filtering between the
two nearest levels.  The table (``to_manifest``) is all a shader needs to reproduce ``z(w)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["LobeLadder", "lobe_ladder", "z_of_w", "texel_power", "lobe_half_angle", "lobe_sigma"]

Z_OF_W_RULE = "piecewise-linear in log2(1+w) over powers"


def _check_w(w: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(w, dtype=np.float64)
    if np.any(np.isnan(a)):
        raise ValueError(f"cosine power w contains {int(np.count_nonzero(np.isnan(a)))} NaN value(s)")
    if np.any(a < 0):
        raise ValueError(f"cosine power w must be >= 0, got min {float(a.min())!r}")
    return a


def z_of_w(w: ArrayLike, powers: ArrayLike) -> NDArray[np.float64]:
    """Continuous mip level for cosine power(s) ``w`` from a bare, strictly decreasing ``powers`` table.

    Piecewise-linear interpolation of the level index over ``x = log2(1 + w)`` at the nodes
    ``x_k = log2(1 + powers[k])``.  ``w >= powers[0]`` (and ``w = +inf``) gives 0;
    ``w <= powers[-1]`` gives ``L - 1`` (clamped: the widest level).  Returns float64 with the
    shape of ``w``.  Raises ``ValueError`` for negative or NaN ``w`` and for a bad table.
    """
    p = np.asarray(powers, dtype=np.float64)
    if p.ndim != 1 or p.size < 1:
        raise ValueError(f"powers must be a non-empty 1-D table, got shape {p.shape}")
    if not np.all(np.isfinite(p)) or np.any(p < 0):
        raise ValueError("powers must be finite and >= 0")
    if np.any(np.diff(p) >= 0):
        raise ValueError(f"powers must be strictly decreasing, got {p.tolist()}")
    a = _check_w(w)
    if p.size == 1:
        return np.zeros(a.shape, dtype=np.float64)
    xk = np.log2(1.0 + p)[::-1]  # increasing
    kk = np.arange(p.size, dtype=np.float64)[::-1]
    with np.errstate(over="ignore"):
        x = np.log2(1.0 + np.where(np.isinf(a), p[0], a))
    return np.interp(x, xk, kk).astype(np.float64)


def texel_power(n: int) -> float:
    """Cosine power whose normalized lobe has the angular variance of one face-center texel.

    A face-center texel of an ``n``-texel face spans ``2/n`` rad per axis (variance
    ``(2/n)^2 / 12`` per axis); the normalized ``cos^w`` lobe has ``E[1 - cos] = 1/(w + 2)``,
    i.e. about ``1/(w + 2)`` per axis for small angles.  Equal: ``w = 3 n^2 - 2``.
    """
    if n < 1:
        raise ValueError(f"face size must be >= 1, got {n}")
    return max(3.0 * n * n - 2.0, 1.0)


def lobe_half_angle(w: ArrayLike) -> NDArray[np.float64]:
    """Half-maximum angle (radians) of ``cos^w``: ``acos(2^(-1/w))``; pi/2 for ``w = 0``."""
    a = _check_w(w)
    with np.errstate(divide="ignore"):
        return np.where(a > 0, np.arccos(np.exp2(-1.0 / np.maximum(a, 1e-300))), np.pi / 2)


def lobe_sigma(w: ArrayLike) -> NDArray[np.float64]:
    """RMS angle per axis (radians) of the normalized lobe, small-angle: ``1/sqrt(w + 2)``."""
    return 1.0 / np.sqrt(_check_w(w) + 2.0)


@dataclass(frozen=True)
class LobeLadder:
    """Face size and normalized cosine power of each level of a chain.

    ``sizes[k] = N_0 >> k`` (texels per face edge); ``powers`` strictly decreasing, ``powers[0]``
    the equivalent power of one level-0 texel (level 0 is the unfiltered capture).
    """

    sizes: tuple[int, ...]
    powers: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.sizes) != len(self.powers) or not self.sizes:
            raise ValueError("LobeLadder needs as many sizes as powers, at least one")
        for k, s in enumerate(self.sizes):
            if s != max(self.sizes[0] >> k, 1) or s < 1:
                raise ValueError(f"LobeLadder sizes must be N_0 >> k, got {self.sizes}")
        p = np.asarray(self.powers, dtype=np.float64)
        if not np.all(np.isfinite(p)) or np.any(p < 0) or np.any(np.diff(p) >= 0):
            raise ValueError(f"LobeLadder powers must be finite, >= 0 and strictly decreasing, got {self.powers}")

    @property
    def levels(self) -> int:
        return len(self.sizes)

    def z(self, w: ArrayLike) -> NDArray[np.float64]:
        """Continuous level for power(s) ``w`` (float64, shape of ``w``); see :func:`z_of_w`."""
        return z_of_w(w, self.powers)

    def to_manifest(self) -> dict[str, Any]:
        """JSON-ready table: ``{"sizes", "powers", "z_of_w"}`` (enough for a shader to reproduce z(w))."""
        return {"sizes": [int(s) for s in self.sizes], "powers": [float(p) for p in self.powers], "z_of_w": Z_OF_W_RULE}

    @staticmethod
    def from_manifest(m: dict[str, Any]) -> "LobeLadder":
        """Inverse of :meth:`to_manifest` (raises ``ValueError``/``KeyError`` on a bad table)."""
        if m.get("z_of_w", Z_OF_W_RULE) != Z_OF_W_RULE:
            raise ValueError(f"unknown z_of_w rule {m.get('z_of_w')!r}")
        return LobeLadder(tuple(int(s) for s in m["sizes"]), tuple(float(p) for p in m["powers"]))


def lobe_ladder(n: int, levels: int | None = None, sigma_texels: float = 0.5, w_min: float = 1.0) -> LobeLadder:
    """The ladder for a chain whose level 0 has ``n`` texels per face edge.

    ``levels`` defaults to the full chain down to 1 texel (``n.bit_length()`` levels).  Level 0:
    :func:`texel_power`.  Level ``k >= 1``: the sharpest lobe whose RMS angle is at least
    ``sigma_texels`` face-center texels of that level, ``w_k = (N_k / (2 sigma_texels))^2 - 2``,
    never below ``w_min``; the tail is kept strictly decreasing (one octave of ``1 + w`` per level
    where the floor binds).  See ``docs/lobes.md``.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"face size must be a positive integer, got {n!r}")
    n = int(n)
    full = n.bit_length()
    if levels is None:
        levels = full
    if not 1 <= levels <= full:
        raise ValueError(f"levels must be in 1..{full} for a {n}-texel face, got {levels}")
    if not (sigma_texels > 0 and math.isfinite(sigma_texels)):
        raise ValueError(f"sigma_texels must be > 0, got {sigma_texels}")
    if not (w_min >= 0 and math.isfinite(w_min)):
        raise ValueError(f"w_min must be finite and >= 0, got {w_min}")
    sizes = tuple(max(n >> k, 1) for k in range(levels))
    w = [texel_power(n)]
    for k in range(1, levels):
        w.append(max((sizes[k] / (2.0 * sigma_texels)) ** 2 - 2.0, w_min))
    # strictly decreasing from the end: where the floor binds, step up one octave of (1 + w)
    for k in range(levels - 2, -1, -1):
        if w[k] <= w[k + 1]:
            w[k] = 2.0 * (1.0 + w[k + 1]) - 1.0
    return LobeLadder(sizes, tuple(float(x) for x in w))
