"""The exact footprint of a cosine lobe seen from a probe (float64 reference of the mip shift).

For a shading point ``x``, a lobe axis ``d`` and a power ``w``, ``K`` directions ``u`` are drawn
from the normalized cos^w lobe around ``d`` (stratified: ``cos(theta) = U^(1/(w+1))``, ``phi``
uniform), each traced through the street's three planes from ``x`` (the rays that hit no plane
see the sky: their direction, at infinity), and the hit points are seen from the probe ``p`` as
unit vectors ``v``.  The footprint's second moments about their mean direction ``m`` (tangential
parts ``v - (v.m) m``, so ``|.|^2 = sin^2`` of the angle to ``m``) give a 2x2 covariance ``C``.
A cos^W lobe has per-axis ``E[sin^2] / 2 = 1 / (W + 3)`` exactly, so the equivalent powers are

* ``w_iso = 1 / sqrt(det C) - 3`` (same solid angle: the level an isotropic lookup should read),
* ``w_minor = 1 / c_min - 3`` and ``w_major = 1 / c_max - 3`` (the footprint's axes),

clamped to >= 0.  No small-angle or equal-obliquity assumption; the wide lobes' spill onto the
other planes and the sky is included.  ``docs/runtime.md`` ("Oblique, anisotropic mip shift").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.runtime.limits import FAR
from envcap.runtime.parallax import clamp_to_street, exit_distance


@dataclass(frozen=True)
class ExactFootprint:
    """``(...)`` arrays: equivalent powers ``w_iso``, ``w_minor``, ``w_major`` of the footprint
    seen from the probe (``w_minor >= w_iso >= w_major``), its mean direction ``m`` ``(..., 3)``
    and long axis ``major`` ``(..., 3)``; ``sky_fraction``: the share of the lobe that hits no plane."""

    w_iso: NDArray[np.float64]
    w_minor: NDArray[np.float64]
    w_major: NDArray[np.float64]
    m: NDArray[np.float64]
    major: NDArray[np.float64]
    sky_fraction: NDArray[np.float64]


def lobe_samples(d: ArrayLike, w: ArrayLike, samples: int = 1024, seed: int = 0) -> NDArray[np.float64]:
    """``(M, K, 3)`` unit directions drawn from the normalized cos^w lobe around each of ``d``
    ``(M, 3)`` (``w`` ``(M,)``, > 0), ``K = samples``: stratified in ``U`` with one random
    rotation per lookup, fixed ``seed``."""
    d = np.asarray(d, np.float64).reshape(-1, 3)
    w = np.broadcast_to(np.asarray(w, np.float64), d.shape[:1])
    if samples < 16 or np.any(~(w > 0)):
        raise ValueError("need >= 16 samples and lobe powers w > 0")
    rng = np.random.default_rng(seed)
    k = np.arange(samples)
    u = (k + rng.random((d.shape[0], samples))) / samples
    phi = 2 * np.pi * ((k * 0.6180339887498949 + rng.random((d.shape[0], 1))) % 1.0)
    ct = u ** (1.0 / (w[:, None] + 1.0))
    st = np.sqrt(np.maximum(0.0, 1.0 - ct * ct))
    a = np.where(np.abs(d[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    e1 = np.cross(d, a)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(d, e1)
    return (st * np.cos(phi))[..., None] * e1[:, None] + (st * np.sin(phi))[..., None] * e2[:, None] \
        + ct[..., None] * d[:, None]


def exact_footprint(x: ArrayLike, d: ArrayLike, w: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int,
                    samples: int = 1024, seed: int = 0) -> ExactFootprint:
    """The exact footprint (:class:`ExactFootprint`) of ``M`` lookups: shading points ``x``,
    unit lobe axes ``d`` (``(M, 3)``), powers ``w`` ``(M,)`` (> 0), probe positions ``p`` and
    ``planes`` ``(3,)`` or ``(M, 3)`` (world m, ``along`` the street axis); float64."""
    d = np.asarray(d, np.float64).reshape(-1, 3)
    m_ = d.shape[0]
    x, p, planes = (np.broadcast_to(np.asarray(a, np.float64).reshape(-1, 3), (m_, 3)) for a in (x, p, planes))
    u = lobe_samples(d, w, samples, seed)                                     # (M, K, 3)
    xc = clamp_to_street(x, planes, along)
    t = exit_distance(xc[:, None], u, planes[:, None], along)                  # (M, K)
    hit = t < FAR
    v = np.where(hit[..., None], xc[:, None] + t[..., None] * u - p[:, None], u)
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    m = v.mean(axis=1)
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    tang = v - (v * m[:, None]).sum(-1, keepdims=True) * m[:, None]
    a = np.where(np.abs(m[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    f1 = np.cross(m, a)
    f1 /= np.linalg.norm(f1, axis=1, keepdims=True)
    f2 = np.cross(m, f1)
    c1 = (tang * f1[:, None]).sum(-1)
    c2 = (tang * f2[:, None]).sum(-1)
    cov = np.stack([np.stack([(c1 * c1).mean(1), (c1 * c2).mean(1)], -1),
                    np.stack([(c1 * c2).mean(1), (c2 * c2).mean(1)], -1)], -2)
    ev, evec = np.linalg.eigh(cov)                                             # ascending
    ev = np.maximum(ev, 1e-300)
    w_iso = np.maximum(1.0 / np.sqrt(ev[:, 0] * ev[:, 1]) - 3.0, 0.0)
    major = evec[:, 0, 1, None] * f1 + evec[:, 1, 1, None] * f2
    return ExactFootprint(w_iso, np.maximum(1.0 / ev[:, 0] - 3.0, 0.0), np.maximum(1.0 / ev[:, 1] - 3.0, 0.0),
                          m, major, 1.0 - hit.mean(axis=1))
