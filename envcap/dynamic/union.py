"""The union of many spheres' caps seen by one BRDF lobe, on the lobe's rings: the ``"rings"``
combine rule (numpy twin of ``envcap_ring_union`` in ``shaders/runtime/envcap_dynamic_spheres.glsl``;
derivation in ``docs/dynamic.md``, "The union on the lobe's rings").

The fraction of the normalized lobe ``max(0, u.C)^w`` inside the union of caps ``k`` (half-angle
``theta_k``, axis ``D_k`` at ``gamma_k`` from ``C`` and azimuth ``psi_k`` about it) is exactly

    U = int_0^1 chi_U(alpha(z)) dz,   z = cos^(w+1) alpha,

``chi_U`` the covered fraction of the ring ``{angle(u, C) = alpha}``: the union of the arcs
``[psi_k - phi_k, psi_k + phi_k]``, ``1 - cos phi_k = q_k`` as in :mod:`envcap.dynamic.cap_lobe`.
Rings below ``A = max_k (theta_k - gamma_k)`` are wholly covered (``1 - G(A)``, ``G = cos^(w+1)``);
the others, from ``L`` (the lowest ring any cap reaches past ``A``) to ``B`` (the highest, at most
``pi/2``), by ``nodes``-point Gauss-Legendre in ``z`` (the map of ``cap_lobe``), the arcs merged
exactly on each node ring (:func:`arc_union`, ``O(K^2)`` without sorting).  The nodes miss the
kinks of the caps' edges inside ``[L, B]``; the same nodes integrate each cap alone (``F~_k``), whose
exact value on ``[L, B]`` is known (``F_k = f_k``, less ``1 - G(L)`` for a cap that holds ``C``,
from :func:`envcap.dynamic.cap_lobe.cap_lobe_fraction`), and the node union is rescaled by
``sum F / sum F~`` (a ratio estimator):

    U = 1 - G(A) + U~ sum_k S_k / sum_k F~_k,   S_k = F~_k + omega_k (F_k - F~_k),

``omega_k = clamp(1 - rho_k / FADE, 0, 1)``, ``rho_k`` the share of cap ``k``'s partial rings
(in ``z``) below ``L``, where ``F_k`` is not its light on ``[L, B]`` (continuous in the inputs).
Exact for one cap, for disjoint caps (``U~ = sum F~``: the sum) and for identical ones (the one);
clamped to ``[max f, min(1, sum f)]``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.dynamic.cap_lobe import cap_half_angle, gauss_nodes, one_minus_exp
from envcap.dynamic.lobe_product import any_perpendicular, clean_power, cos_power, unit_or
from envcap.runtime.glsl_math import dot3

UNION_NODES = 8
"""Gauss-Legendre rings of the union (GLSL ``ENVCAP_UNION_NODES``, 1..8)."""
FADE = 0.1
"""A cap whose partial rings lie more than this share (in ``z``) below ``L`` keeps its node value."""


def wrap_pi(x: NDArray, dtype: Any) -> NDArray:
    """``x`` in ``(-2 pi, 2 pi)`` wrapped to ``(-pi, pi]``."""
    two_pi, pi = dtype(2 * np.pi), dtype(np.pi)
    return np.where(x > pi, x - two_pi, np.where(x <= -pi, x + two_pi, x)).astype(dtype)


def arc_union(phi: NDArray, x: NDArray, dtype: Any = np.float64) -> NDArray:
    """Covered fraction of a circle by arcs of half-widths ``phi`` ``(..., K)`` (rad, ``[0, pi]``;
    0: no arc) centered at relative azimuths ``x`` ``(..., K, K)`` (``x[i, j]``: arc ``i``'s center
    from arc ``j``'s, in ``(-pi, pi]``; only ``i < j`` is read, ``x[j, i] = -x[i, j]``).

    The uncovered length is the sum, over arc ends not strictly inside another arc, of the gap to
    the next arc start.  Per pair one difference ``delta = end_i - end_j`` decides both ends (ties:
    the lower index keeps its end), so near-identical arcs never hide each other's gap."""
    K = phi.shape[-1]
    two_pi = dtype(2 * np.pi)
    live = phi > 0
    covered = np.zeros(phi.shape, bool)
    gap = np.where(live, two_pi - dtype(2) * phi, dtype(0))
    for i in range(K):
        for j in range(i + 1, K):
            both = live[..., i] & live[..., j]
            delta = x[..., i, j] + (phi[..., i] - phi[..., j])
            for me, other, d, wins in ((i, j, delta, True), (j, i, -delta, False)):
                dn = np.where(d > 0, d - two_pi, d)                       # (-2 pi, 0]: my end behind the other's
                v = -dn - dtype(2) * phi[..., other]                      # the other's start, ahead of my end
                inside = ((v < 0) & (dn < 0)) | ((dn == 0) & (not wins))
                covered[..., me] |= both & inside
                gap[..., me] = np.where(both & ~inside, np.minimum(gap[..., me], np.where(v < 0, v + two_pi, v)),
                                        gap[..., me])
    uncovered = np.sum(np.where(live & ~covered, gap, dtype(0)), axis=-1)
    frac = dtype(1) - uncovered / two_pi
    frac = np.where(np.any(phi >= dtype(np.pi), axis=-1), dtype(1), frac)
    return np.where(np.any(live, axis=-1), np.clip(frac, dtype(0), dtype(1)), dtype(0)).astype(dtype)


def ring_union(D: ArrayLike, t: ArrayLike, C: ArrayLike, w: ArrayLike, f: ArrayLike, nodes: int = UNION_NODES,
               dtype: Any = np.float64) -> NDArray:
    """``U`` ``(...)``: the fraction of the BRDF lobe ``(C, w)`` (``C`` ``(..., 3)``, any length;
    ``w`` ``(...)``) blocked by the union of the sphere lobes ``(D, t)`` (``(..., K, 3)``,
    ``(..., K)``, read as caps as :func:`envcap.dynamic.cap_lobe.cap_lobe_product` does; ``D = 0``: a
    sphere holding the point), given each one's blocked fraction ``f`` ``(..., K)`` (0 for an
    empty slot: the cap is left out).  Module docstring; ``dtype=np.float32``: the GLSL order."""
    D = np.asarray(D, dtype=dtype)
    t = np.asarray(t, dtype=dtype)
    f = np.clip(np.asarray(f, dtype=dtype), dtype(0), dtype(1))
    shp = np.broadcast_shapes(D.shape[:-2], t.shape[:-1], f.shape[:-1], np.shape(C)[:-1], np.shape(w))
    K = D.shape[-2]
    D = np.broadcast_to(D, shp + (K, 3))
    t, f = np.broadcast_to(t, shp + (K,)), np.broadcast_to(f, shp + (K,))
    c, _ = unit_or(np.broadcast_to(np.asarray(C, dtype=dtype), shp + (3,)), np.array([0, 0, 1], dtype=dtype), dtype)
    w = clean_power(np.broadcast_to(np.asarray(w, dtype=dtype), shp), dtype)
    cK = np.broadcast_to(c[..., None, :], shp + (K, 3))
    d, _ = unit_or(D, cK, dtype)
    cos_g = dot3(d, cK)
    gamma = np.arctan2(np.sqrt(dot3(np.cross(d, cK), np.cross(d, cK))), cos_g).astype(dtype)
    theta = cap_half_angle(t, dtype)
    e1 = any_perpendicular(c, dtype)
    e2 = np.cross(c, e1).astype(dtype)
    py, px = dot3(d, e2[..., None, :]), dot3(d, e1[..., None, :])
    psi = np.where((px != 0) | (py != 0), np.arctan2(py, px), dtype(0)).astype(dtype)
    live = f > 0
    h, pi = dtype(np.pi / 2), dtype(np.pi)
    lo = np.where(live, np.minimum(np.maximum(gamma - theta, dtype(0)), h), h)
    hi = np.where(live, np.minimum(gamma + theta, h), dtype(0))
    full = np.where(live, np.minimum(np.maximum(theta - gamma, dtype(0)), h), dtype(0))
    A = np.max(full, axis=-1)
    L = np.maximum(A, np.min(lo, axis=-1))
    B = np.max(hi, axis=-1)
    p1 = w + dtype(1)
    GA, GL, GB = (cos_power(v, p1, dtype) for v in (A, L, B))
    span = np.where(B > L, GL - GB, dtype(0))
    # per cap: the q of cap_lobe's rings, and the share rho of its partial rings below L
    sA, cA = np.sin(dtype(0.5) * (theta - gamma)), np.cos(dtype(0.5) * (theta - gamma))
    sB, cB = np.sin(dtype(0.5) * (theta + gamma)), np.cos(dtype(0.5) * (theta + gamma))
    sg = np.sin(gamma)
    x = wrap_pi(psi[..., :, None] - psi[..., None, :], dtype)
    U_n = np.zeros(shp, dtype)
    F_n = np.zeros(shp + (K,), dtype)
    for uk, wk in zip(*gauss_nodes(nodes)):
        z = GL + (GB - GL) * dtype(uk)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            lam = np.log(z) / p1
            m = one_minus_exp(lam, dtype)[..., None]
            s2 = np.sqrt(np.maximum(dtype(0.5) * m, dtype(0)))
            c2 = np.sqrt(np.maximum(dtype(1) - dtype(0.5) * m, dtype(0)))
            num = dtype(2) * (sA * c2 + cA * s2) * (sB * c2 - cB * s2)
            den = dtype(2) * s2 * c2 * sg
            q = np.where(den > 0, num / np.where(den > 0, den, dtype(1)), np.where(num > 0, dtype(2), dtype(0)))
        q = np.where(np.isnan(q), dtype(0), np.minimum(np.maximum(q, dtype(0)), dtype(2)))
        phi = np.where(live, dtype(2) * np.arctan2(np.sqrt(q), np.sqrt(dtype(2) - q)), dtype(0)).astype(dtype)
        wt = span * dtype(wk)
        U_n = U_n + wt * arc_union(phi, x, dtype)
        F_n = F_n + wt[..., None] * phi * dtype(1 / np.pi)
    a = np.minimum(np.abs(theta - gamma), h)
    b = np.minimum(np.minimum(gamma + theta, dtype(2) * pi - gamma - theta), h)
    Ga, Gb = cos_power(a, p1[..., None], dtype), cos_power(b, p1[..., None], dtype)
    GLk = GL[..., None]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rho = np.where(Ga > Gb, np.clip((Ga - GLk) / np.where(Ga > Gb, Ga - Gb, dtype(1)), dtype(0), dtype(1)),
                       np.where(a < L[..., None], dtype(1), dtype(0)))
    omega = np.clip(dtype(1) - rho / dtype(FADE), dtype(0), dtype(1))
    F = f - np.where(theta > gamma, dtype(1) - GLk, dtype(0))
    S = np.sum(np.where(live, F_n + omega * (F - F_n), dtype(0)), axis=-1)
    Fsum = np.sum(F_n, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        part = np.where(Fsum > 0, U_n * (S / np.where(Fsum > 0, Fsum, dtype(1))), S)
    U = dtype(1) - GA + np.maximum(part, dtype(0))
    return np.clip(U, np.max(f, axis=-1), np.minimum(np.sum(f, axis=-1), dtype(1))).astype(dtype)
