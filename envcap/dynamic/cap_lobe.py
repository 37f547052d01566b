"""The light a spherical cap blocks from a cosine lobe, by a few-node integral over the lobe's
rings: envcap's replacement for the paper's Eq. 7 (numpy twin of ``envcap_cap_lobe_product`` in
``shaders/runtime/envcap_dynamic.glsl``; derivation in ``docs/dynamic.md``, "A better Eq. 7").

The fraction of a lobe ``max(0, u.C)^w`` (normalized: total 1) inside the cap of half-angle
``theta`` about ``D`` (``gamma`` = angle between ``D`` and ``C``) is exactly

    f = int_0^{pi/2} chi(alpha) dF(alpha),   F(alpha) = 1 - cos^(w+1) alpha,

``chi(alpha)`` the fraction of the ring ``{angle(u, C) = alpha}`` inside the cap:
``chi = phi / pi``, ``1 - cos phi = q = 2 sin((theta + alpha - gamma)/2) sin((theta - alpha +
gamma)/2) / (sin alpha sin gamma)`` clamped to ``[0, 2]``.  Rings with ``alpha < |theta - gamma|``
are wholly inside (``theta > gamma``) or outside; rings past ``min(gamma + theta, 2 pi - gamma -
theta)`` wholly inside when the cap wraps past ``-C`` (``gamma + theta > pi``), else outside.  The
partial rings are integrated in the lobe's own measure ``z = cos^(w+1) alpha`` (uniform: sharp
lobes need no more nodes than wide ones) with ``z`` from ``G(a)`` to ``G(b)`` mapped as
``u = (1 - cos s) / 2`` (which removes ``chi``'s square-root ends) and ``nodes``-point
Gauss-Legendre in ``s``.  With 4 nodes the largest error over ``theta`` 1-90 deg, ``w`` 0-10^5 and
all ``gamma`` is 1.3e-3 of the lobe's light (the paper's Eq. 7: 0.27; ``envcap bench dynamic``).

The axis ``M`` is the blocked light's centroid: ring ``alpha`` contributes ``chi cos alpha C +
sin alpha sin phi / pi P`` (``P`` the unit perpendicular to ``C`` towards ``D``), wholly inside
rings ``C``.  Inputs as :func:`envcap.dynamic.lobe_product.lobe_product` (the cap from ``t``
through ``cos theta = t / (1 + t)``, the inverse of :func:`envcap.dynamic.sphere_lobe.sphere_lobe`).
"""

from __future__ import annotations

from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.dynamic.lobe_product import LobeProduct, any_perpendicular, clean_power, cos_power, lobe_product, unit_or
from envcap.runtime.glsl_math import dot3

CAP_NODES = 4
"""Gauss-Legendre nodes over the partial rings (GLSL ``ENVCAP_CAP_NODES``, 1..8)."""
EXPM1_SERIES_ABOVE = -0.03
"""For ``lambda = ln z / (w + 1)`` above this, ``1 - e^lambda`` is its 4-term series (float32)."""

OcclusionForm = Literal["envcap", "paper"]
"""How the light a sphere blocks from a lobe is approximated: ``"envcap"`` (the ring integral of
this module) or ``"paper"`` (Eq. 4-7).  GLSL: ``#define ENVCAP_DYNAMIC_PAPER_FORM`` selects
``"paper"`` in ``envcap_occlusion``."""


def check_form(form: str) -> None:
    """A clear error for an unknown :data:`OcclusionForm`."""
    if form not in get_args(OcclusionForm):
        raise ValueError(f"occlusion form must be one of {get_args(OcclusionForm)}, got {form!r}")


def cap_half_angle(t: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Half-angle ``theta`` (rad) of the cap whose solid angle a lobe of power ``t`` matches:
    ``cos theta = t / (1 + t)``, computed as ``atan2(sqrt(1 + 2 t), t)`` (``t = 0``: pi/2)."""
    t = clean_power(np.asarray(t, dtype=dtype), dtype)
    return np.arctan2(np.sqrt(dtype(1) + dtype(2) * t), t).astype(dtype)


def gauss_nodes(nodes: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(u_k, W_k)``: ring positions in ``[0, 1]`` and weights (sum 1) of the ``nodes``-point rule."""
    if not 1 <= int(nodes) <= 8:
        raise ValueError(f"nodes must be in 1..8, got {nodes}")
    x, wg = np.polynomial.legendre.leggauss(int(nodes))
    s = (x + 1) * (np.pi / 2)
    wk = wg * np.sin(s)
    return (1 - np.cos(s)) / 2, wk / wk.sum()


def one_minus_exp(lam: NDArray, dtype: Any) -> NDArray:
    """``1 - e^lam`` for ``lam <= 0``: ``-expm1`` in float64; the GLSL form in float32."""
    with np.errstate(over="ignore", invalid="ignore"):
        if np.dtype(dtype) == np.float64:
            return -np.expm1(lam)
        series = -lam * (dtype(1) + lam * (dtype(0.5) + lam * (dtype(1 / 6) + lam * dtype(1 / 24))))
        return np.where(lam > dtype(EXPM1_SERIES_ABOVE), series, dtype(1) - np.exp(lam)).astype(dtype)


def cap_lobe_fraction(theta: ArrayLike, gamma: ArrayLike, w: ArrayLike, nodes: int = CAP_NODES,
                      dtype: Any = np.float64) -> tuple[NDArray, NDArray, NDArray]:
    """``(f, vc, vp)``: the fraction ``f`` of the normalized lobe of power ``w`` inside the cap
    (``theta``, ``gamma`` in rad, ``(...)``), and the blocked light's first moment along ``C``
    (``vc``) and along ``P`` (``vp``, the perpendicular towards the cap).  ``dtype=np.float32``:
    the GLSL order."""
    theta, gamma = (np.asarray(a, dtype=dtype) for a in (theta, gamma))
    w = clean_power(np.asarray(w, dtype=dtype), dtype)
    theta, gamma, w = np.broadcast_arrays(theta, gamma, w)
    h, pi = dtype(np.pi / 2), dtype(np.pi)
    a = np.minimum(np.abs(gamma - theta), h)
    b = np.minimum(np.minimum(gamma + theta, dtype(2) * pi - gamma - theta), h)
    p1 = w + dtype(1)
    Ga, Gb = cos_power(a, p1, dtype), cos_power(b, p1, dtype)
    f = np.where(theta > gamma, dtype(1) - Ga, dtype(0)) + np.where(gamma + theta > pi, Gb, dtype(0))
    vc = f.copy()
    vp = np.zeros_like(f)
    span = np.where(b > a, Ga - Gb, dtype(0))
    sA, cA = np.sin(dtype(0.5) * (theta - gamma)), np.cos(dtype(0.5) * (theta - gamma))
    sB, cB = np.sin(dtype(0.5) * (theta + gamma)), np.cos(dtype(0.5) * (theta + gamma))
    sg = np.sin(gamma)
    for uk, wk in zip(*gauss_nodes(nodes)):
        z = Ga + (Gb - Ga) * dtype(uk)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            lam = np.log(z) / p1                                   # ln cos alpha (z = 0: -inf)
            m = one_minus_exp(lam, dtype)                          # 1 - cos alpha
            s2 = np.sqrt(np.maximum(dtype(0.5) * m, dtype(0)))     # sin(alpha / 2)
            c2 = np.sqrt(np.maximum(dtype(1) - dtype(0.5) * m, dtype(0)))
            sin_a = dtype(2) * s2 * c2
            num = dtype(2) * (sA * c2 + cA * s2) * (sB * c2 - cB * s2)
            den = sin_a * sg
            q = np.where(den > 0, num / np.where(den > 0, den, dtype(1)), dtype(2))
        q = np.minimum(np.maximum(q, dtype(0)), dtype(2))          # NaN -> 0 (np.maximum keeps NaN: cleaned below)
        q = np.where(np.isnan(q), dtype(0), q)
        chi = dtype(2 / np.pi) * np.arctan2(np.sqrt(q), np.sqrt(dtype(2) - q))   # asin(sqrt(q / 2)): GPU asin is poor
        sin_phi = np.sqrt(q * (dtype(2) - q))
        wt = span * dtype(wk)
        f = f + wt * chi
        vc = vc + wt * (chi * (dtype(1) - m))
        vp = vp + wt * (sin_a * sin_phi * dtype(1 / np.pi))
    return f.astype(dtype), vc.astype(dtype), vp.astype(dtype)


def cap_lobe_product(D: ArrayLike, C: ArrayLike, t: ArrayLike, w: ArrayLike, nodes: int = CAP_NODES,
                     dtype: Any = np.float64) -> LobeProduct:
    """The envcap form for the occluder lobe ``(D, t)`` (read as its cap) and the BRDF lobe
    ``(C, w)``: ``integral = 2 pi f / (1 + w)`` (sr, for ``|Cv| = 1``, the quantity Eq. 7
    approximates), ``axis`` the blocked light's centroid (``D``'s direction when nothing is
    blocked), ``peak = f`` (the blocked fraction of the lobe).  Limits as Eq. 4-7: ``D = 0`` ->
    ``D = C`` (a containing sphere: ``t = 0``, ``f = 1``); ``C = 0`` -> ``(0, 0, 1)``."""
    D, C = (np.asarray(a, dtype=dtype) for a in (D, C))
    D, C = np.broadcast_arrays(D, C)
    w = clean_power(np.asarray(w, dtype=dtype), dtype)
    c, _ = unit_or(C, np.array([0, 0, 1], dtype=dtype), dtype)
    d, _ = unit_or(D, c, dtype)
    cos_g = dot3(d, c)
    dxc = np.cross(d, c).astype(dtype)
    gamma = np.arctan2(np.sqrt(dot3(dxc, dxc)), cos_g).astype(dtype)
    P, _ = unit_or(d - cos_g[..., None] * c, any_perpendicular(c, dtype), dtype)
    theta = cap_half_angle(t, dtype)
    f, vc, vp = cap_lobe_fraction(theta, gamma, w, nodes, dtype)
    sc = np.maximum(np.abs(vc), np.abs(vp))            # scaled first: tiny moments would underflow in |v|
    with np.errstate(divide="ignore", invalid="ignore"):
        vc, vp = (np.where(sc > 0, x / np.where(sc > 0, sc, dtype(1)), dtype(0)).astype(dtype) for x in (vc, vp))
    M, _ = unit_or(vc[..., None] * c + vp[..., None] * P, d, dtype)
    integral = dtype(2 * np.pi) * f / (dtype(1) + w)
    return LobeProduct(M.astype(dtype), f.astype(dtype), integral.astype(dtype), gamma)


def occlusion(D: ArrayLike, C: ArrayLike, t: ArrayLike, w: ArrayLike, form: OcclusionForm = "envcap",
              dtype: Any = np.float64) -> LobeProduct:
    """The light the sphere lobe ``(D, t)`` blocks from the BRDF lobe ``(C, w)`` in ``form``
    (twin of GLSL ``envcap_occlusion``): :func:`cap_lobe_product` or the paper's Eq. 4-7
    (:func:`envcap.dynamic.lobe_product.lobe_product`).  Shapes as there."""
    check_form(form)
    if form == "paper":
        return lobe_product(D, C, t, w, dtype=dtype)
    return cap_lobe_product(D, C, t, w, dtype=dtype)
