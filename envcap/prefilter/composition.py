"""Lobe algebra of the composed filter: which earlier level each level is filtered from, and with
which difference lobe (``quality="composed"``, :mod:`envcap.prefilter.composed`).

A normalized zonal lobe ``K(d.u)`` acts on the spherical harmonics of degree ``l`` of the
environment as multiplication by its Legendre coefficient ``lambda_l = E[P_l(d.u)]``
(Funk-Hecke), so lobes compose by multiplying coefficients.  For the normalized ``cos^w`` lobe
``lambda_1 = r(w) = (w + 1) / (w + 2)`` (the mean cosine; ``1 - r = 1 / (w + 2)`` is the lobe's
per-axis variance for small angles).  Filtering level ``j`` with ``cos^w_d``, ``r(w_d) =
r(w_k) / r(w_j)``, therefore gives exactly level ``k``'s ``lambda_1`` (to first order: variances
add), and its other coefficients approximately (``docs/prefilter.md`` measures the rest).
"""

from __future__ import annotations

from dataclasses import dataclass

from envcap.core.lobes import LobeLadder
from envcap.prefilter.footprint import LOOP_BUDGET, footprint_theta, loop_estimate

__all__ = ["COMPOSED_EPS", "TAYLOR_MAX_THETA", "TAYLOR_MIN_SIZE", "LevelStep", "composition_plan", "mean_cosine",
           "power_of_mean_cosine", "ratio_needed", "truncated_power"]

COMPOSED_EPS = 1e-3
"""Footprint truncation: weights below this fraction of the lobe's peak are skipped, and the
lobe's power lowered so that the truncated lobe keeps the untruncated mean cosine
(:func:`truncated_power`)."""
TAYLOR_MIN_SIZE = 64
"""Source faces at least this large use the quartic forward-difference weights when the cap is
narrow (:data:`TAYLOR_MAX_THETA`): their solid angles are the texel-centre value to within 2.4e-4;
smaller faces use exact weights and the exact solid-angle table."""
TAYLOR_MAX_THETA = 0.11
"""Widest footprint cap (radians) for the quartic weights; their log error grows as ~w theta^6
(measured: 1.3e-3 at the cap's edge for theta = 0.03, 4e-2 for 0.10; docs/prefilter.md)."""


def mean_cosine(w: float) -> float:
    """``r(w) = (w + 1) / (w + 2)``: the mean of ``d.u`` under the normalized ``max(0, d.u)^w``
    lobe, its first Legendre coefficient."""
    return (w + 1.0) / (w + 2.0)


def power_of_mean_cosine(r: float) -> float:
    """Inverse of :func:`mean_cosine`: ``w = (2 r - 1) / (1 - r)`` (``r`` in ``[1/2, 1)``)."""
    return (2.0 * r - 1.0) / (1.0 - r)


def ratio_needed(w: float) -> float:
    """Least ratio of level ``k``'s lobe variance ``1 / (w + 2)`` to its source level's.

    The composition of two ``cos^w`` lobes has the target's mean cosine but not its shape
    (kurtosis, the hemisphere cut); the difference shrinks as the source lobe gets sharper
    relative to the target and grows as ``w`` shrinks (measured on the canyon street and sky,
    ``docs/prefilter.md``): 4, one level up, for ``w >= 62``; ``4 (64 / (w + 2))^1.5`` below.
    """
    return max(4.0, 4.0 * (64.0 / (w + 2.0)) ** 1.5)


def truncated_power(w: float, eps: float) -> tuple[float, float]:
    """``(w', c)``: the power whose lobe truncated to ``cos^w' >= eps`` (the cone ``d.u >= c``,
    ``c = eps^(1/w')``) has the mean cosine of the untruncated ``cos^w``.

    Truncation drops the tail and narrows the lobe (by ~``eps ln(1/eps)`` of its variance); a
    slightly lower power widens it back.  Mean cosine of the truncated lobe:
    ``(w' + 1) / (w' + 2) (1 - eps c^2) / (1 - eps c)``.  ``(0, 0)`` for ``w = 0``.
    """
    if w <= 0.0:
        return 0.0, 0.0
    target = mean_cosine(w)

    def r_trunc(wp: float) -> float:
        c = eps ** (1.0 / wp)
        return (wp + 1.0) / (wp + 2.0) * (1.0 - eps * c * c) / (1.0 - eps * c)

    lo, hi = 0.25 * w, w
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if r_trunc(mid) > target:
            hi = mid
        else:
            lo = mid
    wp = 0.5 * (lo + hi)
    return wp, eps ** (1.0 / wp)


@dataclass(frozen=True)
class LevelStep:
    """How level ``level`` is filtered: from level ``source`` (0: the input, a *direct* pass) with
    the lobe ``cos^lobe`` (for a composed pass the difference lobe, before truncation
    compensation); ``taylor``: with the quartic forward-difference weights."""

    level: int
    source: int
    lobe: float
    taylor: bool


def _step(ladder: LobeLadder, k: int, j: int, lobe: float) -> LevelStep:
    theta = footprint_theta(lobe, COMPOSED_EPS)
    return LevelStep(k, j, lobe, ladder.sizes[j] >= TAYLOR_MIN_SIZE and theta <= TAYLOR_MAX_THETA)


def _difference_lobe(ladder: LobeLadder, k: int, j: int) -> float | None:
    """``w_d`` with ``r(w_d) r(w_j) = r(w_k)``, or ``None`` where composing level ``k`` from ``j``
    is not possible: no such lobe (``r(w_k) / r(w_j) <= 1/2``), a lobe under half a face-centre
    texel of level ``j`` (its weights would underflow between texel centres), or a footprint over
    the GL loop budget."""
    rd = mean_cosine(float(ladder.powers[k])) / mean_cosine(float(ladder.powers[j]))
    if not 0.5 < rd < 1.0:
        return None
    wd = power_of_mean_cosine(rd)
    if 1.0 / (wd + 2.0) < (1.0 / ladder.sizes[j]) ** 2:
        return None
    if loop_estimate(footprint_theta(wd, COMPOSED_EPS), ladder.sizes[j]) > LOOP_BUDGET:
        return None
    return wd


def composition_plan(ladder: LobeLadder) -> list[LevelStep]:
    """How every level ``k = 1..L-1`` of ``ladder`` is filtered.

    Level 1 is direct.  Level ``k >= 2`` is composed from the coarsest earlier level ``j >= 1``
    whose lobe variance is at most ``1 / ratio_needed(w_k)`` of level ``k``'s (the cheapest
    accurate source) and for which a difference lobe exists (:func:`_difference_lobe`); else it
    is direct, unless a direct footprint would exceed the GL loop budget, in which case it is
    composed from the finest level that fits.
    """
    steps: list[LevelStep] = []
    for k in range(1, ladder.levels):
        wk = float(ladder.powers[k])
        chosen = _step(ladder, k, 0, wk)
        if k >= 2:
            need = ratio_needed(wk)
            for j in range(k - 1, 0, -1):
                wd = _difference_lobe(ladder, k, j)
                if wd is not None and (wk + 2.0) * need <= float(ladder.powers[j]) + 2.0:
                    chosen = _step(ladder, k, j, wd)
                    break
            if chosen.source == 0 and loop_estimate(footprint_theta(wk, COMPOSED_EPS), ladder.sizes[0]) > LOOP_BUDGET:
                for j in range(1, k):
                    wd = _difference_lobe(ladder, k, j)
                    if wd is not None:
                        chosen = _step(ladder, k, j, wd)
                        break
        steps.append(chosen)
    return steps
