"""The top of a rung ladder: rung 0 (the unfiltered capture) read with the cos^w lobe's own
quadrature weights on its 2x2 bilinear footprint, from rung 0's power up to the mirror
(``w = +inf``).  Numpy twin of GLSL ``envcap_rung_top`` (``shaders/runtime/envcap_lobes.glsl``).

Derivation (``docs/lobes.md``, "The top of the ladder"): the exact normalized ``cos^w`` filter of
a level-0 cube at a direction ``d`` is ``sum_u (d.u)^w Omega_u L_u / sum_u (d.u)^w Omega_u`` over
its texel centres ``u``.  For lobes narrower than a texel (``w`` above rung 0's ``3 N^2 - 2``)
only the four centres around ``d`` carry weight (the next ring has ``exp(-2 k)`` of it at the
cell's middle, ``k = w h^2 / 2`` for texel spacing ``h``: under 1 % at ``k >= 2.5``), and as
``w -> inf`` the filter is the texel whose centre is nearest to ``d``, not a bilinear mix.  A
plain bilinear read of rung 0 (the lookup before) is the ``k -> 0`` limit of the wrong kernel.
``top_direction`` computes the four weights ``(d.u_ij)^w Omega_ij`` (``Omega ~ (1 + x^2 + y^2)^-1.5``
on the face plane, the area element) and returns the direction at which one seamless bilinear
read gives the separable kernel with the same marginals ``t_s = W_1. / W``, ``t_t = W_.1 / W``:
exact where the weights are rank one (one texel: the mirror; two along an axis: an edge of the
nearest-texel cell), one ``textureLod`` and the texel reads of a bilinear fetch.

Face plane: the two minor components of ``d`` over the major one (ties X, Y, Z as GL and
:mod:`envcap.core.cube`); the texel centres are symmetric about the face centre, so the
orientation of the face's ``(s, t)`` does not matter and no face table is needed.  A footprint
across one face edge reads, as GL's seamless filter does, the adjacent face's edge row: the
weights use those texels' real centres (at ``1 / (1 - 1/N)`` on this face's plane) and a read
point past the edge is put on the adjacent face as far from the edge and at the same place along
it; a cube corner cell (across two edges) keeps the extended plane's centres.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube_sampling

__all__ = ["MIRROR_POWER", "top_power", "minus_log_cos", "top_direction", "top_fetch"]

MIRROR_POWER = 1e30
"""The power the mirror (rung position -1, ``w = +inf``) is evaluated at: finite, so that
``w * 0`` stays 0 in float32 (GLSL ``envcap_rung_top``); every off-peak weight is ``exp(-huge) = 0``."""


def top_power(u: ArrayLike, n: int, dtype: type = np.float64) -> NDArray:
    """Lobe power of top position ``u`` in ``[-1, 0]`` on ``n``-texel faces: rung 0's power
    ``c - 1`` (``c = 3 n^2 - 1``, :func:`envcap.core.lobes.texel_power` plus one) at ``u = 0``,
    ``c / (1 + u) - 1`` above it (the inverse of :func:`envcap.runtime.rungs.rung_lod_of_w`'s top
    segment), at most :data:`MIRROR_POWER` (``u = -1``: the mirror)."""
    u = np.minimum(np.asarray(u, dtype=dtype), dtype(0))
    c = dtype(3.0 * float(n) * float(n) - 1.0)
    return c / np.maximum(dtype(1) + u, c * dtype(1e-30)) - dtype(1)


def minus_log_cos(f: NDArray[np.float64], xs: NDArray[np.float64], ys: NDArray[np.float64]) -> NDArray[np.float64]:
    """``-log cos`` of the angle between face-plane points ``f`` ``(M, 2)`` and ``(xs, ys)``
    ``(M, K)``, well conditioned for small angles (GLSL ``envcap_rung_top_dir`` in the same steps):
    ``sin^2 = (dx^2 + dy^2 + (f_x dy - f_y dx)^2) / ((1 + |f|^2)(1 + x^2 + y^2))`` from the small
    differences ``dx = x - f_x``, ``dy = y - f_y`` (Lagrange's identity), then
    ``-log cos = -log(1 - sin^2) / 2 = atanh(z)``, ``z = sin^2 / (2 - sin^2)``, by its series to
    ``z^9`` (relative error ``z^10 / 11``: 3e-10 for neighbours 30 degrees apart; it stays finite
    at 90 degrees, where only one-texel faces put a neighbour)."""
    fx, fy = f[:, :1], f[:, 1:]
    dx, dy = xs - fx, ys - fy
    cr = fx * dy - fy * dx
    s2 = (dx * dx + dy * dy + cr * cr) / ((1.0 + fx * fx + fy * fy) * (1.0 + xs * xs + ys * ys))
    z = s2 / (2.0 - s2)
    z2 = z * z
    return z * (1.0 + z2 * (1.0 / 3.0 + z2 * (1.0 / 5.0 + z2 * (1.0 / 7.0 + z2 * (1.0 / 9.0)))))


def top_direction(d: ArrayLike, n: int, w: ArrayLike) -> NDArray[np.float64]:
    """``(..., 3)``: where a seamless bilinear read of an ``n``-texel level returns the separable
    ``cos^w`` quadrature kernel of its 2x2 footprint around unit ``d`` (module docstring; float64)."""
    d = np.asarray(d, dtype=np.float64)
    shape = d.shape
    d = d.reshape(-1, 3)
    w = np.broadcast_to(np.asarray(w, dtype=np.float64), shape[:-1]).reshape(-1)
    a = np.abs(d)
    xmaj = (a[:, 0] >= a[:, 1]) & (a[:, 0] >= a[:, 2])
    ymaj = ~xmaj & (a[:, 1] >= a[:, 2])
    k = np.where(xmaj, 0, np.where(ymaj, 1, 2))
    p = np.where(k == 0, 1, 0)
    q = np.where(k == 2, 1, 2)
    rows = np.arange(d.shape[0])
    ma = a[rows, k]
    f = np.stack([d[rows, p], d[rows, q]], -1) / ma[:, None]          # face-plane coordinates
    nf = float(n)
    i0 = np.floor((f + 1.0) * 0.5 * nf - 0.5)
    ca = 2.0 * (i0 + 0.5) / nf - 1.0                                   # the footprint's centres
    cb = ca + 2.0 / nf
    # a footprint across one face edge: its texels there are the adjacent face's edge row (GL's
    # seamless read), centres at 1 / (1 - 1/n) on this face's plane, solid angle on their own face
    lo, hi = i0 < 0, i0 + 1 > nf - 1
    seam = lo | hi
    one = seam & ~(seam[:, ::-1])                                      # one axis only (not a corner)
    g = nf / max(nf - 1.0, 0.5)
    sx, sy = one[:, :1], one[:, 1:]
    acr_x = np.where(lo[:, :1], [[1, 0, 1, 0]], [[0, 1, 0, 1]]).astype(bool) & sx     # entries across x
    acr_y = np.where(lo[:, 1:], [[1, 1, 0, 0]], [[0, 0, 1, 1]]).astype(bool) & sy
    xs = np.stack([ca[:, 0], cb[:, 0], ca[:, 0], cb[:, 0]], -1)        # order 00, 10, 01, 11
    ys = np.stack([ca[:, 1], ca[:, 1], cb[:, 1], cb[:, 1]], -1)
    lq = np.log(1.0 + xs * xs + ys * ys)
    lq = np.where(acr_x, np.log(1.0 + (1.0 / g) ** 2 + ys * ys), np.where(acr_y, np.log(1.0 + (1.0 / g) ** 2 + xs * xs), lq))
    xs, ys = (np.where(acr_x, np.sign(xs) * g, np.where(acr_y, xs * g, xs)),
              np.where(acr_y, np.sign(ys) * g, np.where(acr_x, ys * g, ys)))
    e = -w[:, None] * minus_log_cos(f, xs, ys) - 1.5 * lq             # log of (d.u)^w Omega_u + a constant
    wt = np.exp(e - e.max(-1, keepdims=True))
    s = wt.sum(-1)
    t = np.stack([wt[:, 1] + wt[:, 3], wt[:, 2] + wt[:, 3]], -1) / s[:, None]
    f2 = ca + t * (2.0 / nf)
    # past the edge: the point on the adjacent face as far from the edge, at the same place along it
    over = np.abs(f2) > 1.0
    bx = (over[:, 0] & one[:, 0])
    by = (over[:, 1] & one[:, 1])
    major = np.ones(d.shape[0])
    major = np.where(bx, 2.0 - np.abs(f2[:, 0]), np.where(by, 2.0 - np.abs(f2[:, 1]), major))
    f2 = np.where(bx[:, None], np.stack([np.sign(f2[:, 0]), f2[:, 1]], -1), f2)
    f2 = np.where(by[:, None], np.stack([f2[:, 0], np.sign(f2[:, 1])], -1), f2)
    out = np.empty_like(d)
    out[rows, k] = np.sign(d[rows, k]) * major
    out[rows, p] = f2[:, 0]
    out[rows, q] = f2[:, 1]
    return out.reshape(shape)


def top_fetch(level0: ArrayLike, d: ArrayLike, layer: ArrayLike, w: ArrayLike) -> NDArray[np.float64]:
    """``(..., C)``: layer ``layer`` (integer per direction) of the cube-map array level
    ``level0`` ``(L, 6, N, N, C)`` along unit ``d`` under the ``cos^w`` lobe's 2x2 footprint
    kernel (:func:`top_direction`; one seamless bilinear read, :func:`envcap.core.cube_sampling.bilinear`)."""
    lv = np.asarray(level0)
    return cube_sampling.bilinear(lv, top_direction(d, lv.shape[-2], w), layer)
