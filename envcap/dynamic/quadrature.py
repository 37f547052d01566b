"""Float64 reference for Eq. 7: the integral of a cosine lobe over a spherical cap, by quadrature
(independent of Eq. 4-7 and of the sphere -> lobe mapping).

``I(theta, gamma, w) = integral over the cap {u : angle(u, D) <= theta} of max(0, u.C)^w du`` (sr),
with ``gamma`` the angle between the cap's axis ``D`` and the lobe's unit axis ``C``: the light a
sphere of ``sin theta = r / l`` blocks from a BRDF lobe of ``|Cv| = 1`` (the paper's Eq. 3 lobe
``|Cv|^w max(0, u.C)^w`` divided by ``|Cv|^w``).

Method: polar coordinates about the cap's axis, ``u.C = cos b cos gamma + sin b sin gamma cos phi``
(``b`` = angle from ``D``, ``phi`` = azimuth from the plane of ``D`` and ``C``),

    I = 2 int_0^theta sin b db int_0^phi_max(b) (cos b cos gamma + sin b sin gamma cos phi)^w dphi,

``phi_max`` where the lobe's horizon cuts the circle.  Both integrals are composite Gauss-Legendre
over panels that grow geometrically away from the lobe's peak (widths ``~ 1 / sqrt(w)``), with
breakpoints at the kinks (where the lobe's horizon touches the circle of
``b``: ``|b - gamma| = pi/2``, ``b + gamma = pi/2`` or ``3 pi/2``), and graded
toward the kinks for powers below 2 (square-root behaviour there), so that powers from 0 to ``10^7``
are resolved.  Checked against closed forms in ``tests/dynamic``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

GAUSS_NODES = 24
"""Gauss-Legendre nodes per panel."""

_X, _W = np.polynomial.legendre.leggauss(GAUSS_NODES)


def panels(lo: float, hi: float, center: float, width: float, kinks: tuple[float, ...] = (),
           graded: bool = False) -> NDArray[np.float64]:
    """Panel edges on ``[lo, hi]``: ``center +- width 2^k`` (k = -2, -1, ...) and the ``kinks``;
    ``graded``: also ``kink +- pi 4^-k`` (k = 1..14), for the square-root kinks of powers < 2."""
    edges = {lo, hi}
    step = width / 4
    while step < 2 * (hi - lo) + width:
        edges.update((center - step, center + step))
        step *= 2
    edges.update(kinks)
    if graded:
        edges.update(kk + sg * math.pi * 4.0 ** -k for kk in kinks for sg in (-1, 1) for k in range(1, 15))
    return np.array(sorted(e for e in edges if lo <= e <= hi))


def gauss(edges: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Nodes and weights of composite Gauss-Legendre over the panels ``edges``."""
    a, b = edges[:-1, None], edges[1:, None]
    half = 0.5 * (b - a)
    return ((a + b) * 0.5 + half * _X).ravel(), (half * _W).ravel()


def azimuth_integral(beta: float, gamma: float, w: float) -> float:
    """``int_0^phi_max (A + B cos phi)^w dphi`` at polar angle ``beta`` (rad)."""
    A, B = math.cos(beta) * math.cos(gamma), math.sin(beta) * math.sin(gamma)
    if A + B <= 0:
        return 0.0
    if B <= 1e-300:
        return math.pi * max(A, 0.0) ** w if w > 0 else math.pi
    phi_max = math.pi if A - B >= 0 else math.acos(max(-1.0, min(1.0, -A / B)))
    width = math.sqrt((A + B) / (max(w, 1.0) * B))
    phi, wt = gauss(panels(0.0, phi_max, 0.0, width, kinks=(phi_max,), graded=w < 2))
    f = np.maximum(A + B * np.cos(phi), 0.0)
    return float(np.sum(wt * (f ** w if w > 0 else (f > 0))))


def cap_lobe_integral(theta: float, gamma: float, w: float) -> float:
    """``I(theta, gamma, w)`` (sr): the cap of half-angle ``theta`` (rad, in ``[0, pi]``; ``pi``
    is the whole sphere) and the lobe ``max(0, u.C)^w`` at angle ``gamma`` (rad) from its axis."""
    theta, gamma, w = float(theta), float(gamma), max(float(w), 0.0)
    if theta <= 0:
        return 0.0
    width = 1.0 / math.sqrt(max(w, 1.0))
    edges = panels(0.0, theta, gamma, width, kinks=(gamma - math.pi / 2, gamma + math.pi / 2,
                                                       math.pi / 2 - gamma, 1.5 * math.pi - gamma), graded=w < 2)
    beta, wt = gauss(edges)
    inner = np.array([azimuth_integral(b, gamma, w) for b in beta])
    return float(2.0 * np.sum(wt * np.sin(beta) * inner))


def union_lobe_fraction(D: NDArray[np.float64], theta: NDArray[np.float64], C: NDArray[np.float64], w: float,
                        rings: int = 32768) -> float:
    """The fraction of the normalized lobe ``max(0, u.C)^w`` (``C`` unit) inside the union of the
    caps ``D`` ``(K, 3)`` (unit axes) of half-angles ``theta`` ``(K,)`` (rad): float64 reference
    for many spheres.  Exact on each ring ``{angle(u, C) = alpha}`` (the union of the caps' arcs,
    swept on the circle), integrated over the lobe's measure ``z = cos^(w+1) alpha`` (uniform in
    ``[0, 1]``) by the midpoint rule with ``rings`` rings, refined as ``z = 1 - (1 - v)^2``
    near ``alpha = 0``.  Error <= 1e-5 at the default (a step of ``chi`` costs ~dz/2; checked
    against :func:`cap_lobe_integral` and Monte Carlo in ``tests/dynamic``)."""
    D = np.asarray(D, np.float64).reshape(-1, 3)
    theta = np.asarray(theta, np.float64).reshape(-1)
    C = np.asarray(C, np.float64)
    w = max(float(w), 0.0)
    if len(D) == 0:
        return 0.0
    v = (np.arange(rings) + 0.5) / rings
    z, dz = 1 - (1 - v) ** 2, 2 * (1 - v) / rings
    alpha = np.arccos(np.clip(np.exp(np.log(z) / (w + 1)), -1, 1))
    perp = np.array([1.0, 0.0, 0.0]) if abs(C[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = perp - (perp @ C) * C
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(C, e1)
    gamma = np.arccos(np.clip(D @ C, -1, 1))
    psi = np.arctan2(D @ e2, D @ e1)                                  # azimuth of each cap's axis
    sa, ca = np.sin(alpha)[:, None], np.cos(alpha)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        cphi = (np.cos(theta) - ca * np.cos(gamma)) / (sa * np.sin(gamma))
    full = (cphi <= -1) | (np.isnan(cphi) & (ca * np.cos(gamma) + 0 >= np.cos(theta)))
    phi = np.where(full, np.pi, np.arccos(np.clip(np.nan_to_num(cphi, nan=2.0), -1, 1)))
    lo = np.mod(psi - phi, 2 * np.pi)
    hi = lo + 2 * phi
    # split arcs that pass 2 pi; empty arcs have phi = 0
    lo2, hi2 = np.where(hi > 2 * np.pi, 0.0, 0.0), np.where(hi > 2 * np.pi, hi - 2 * np.pi, 0.0)
    hi = np.minimum(hi, 2 * np.pi)
    starts, ends = np.concatenate([lo, lo2], axis=1), np.concatenate([hi, hi2], axis=1)
    order = np.argsort(starts, axis=1)
    starts, ends = np.take_along_axis(starts, order, 1), np.take_along_axis(ends, order, 1)
    reach = np.maximum.accumulate(ends, axis=1)
    prev = np.concatenate([np.zeros((rings, 1)), reach[:, :-1]], axis=1)
    covered = np.sum(np.maximum(ends - np.maximum(starts, prev), 0.0), axis=1)
    covered = np.where(np.any(full, axis=1), 2 * np.pi, covered)
    return float(np.sum(dz * covered / (2 * np.pi)))
