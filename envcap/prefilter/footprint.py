"""Lobe footprints on a cube level: the cap a truncated ``cos^w`` lobe covers, its texel
rectangles per face, and the loop count a GL invocation spends on it.

Face frames follow :mod:`envcap.core.cube`: direction ``= N + u A + v B`` (``u`` along columns,
``v`` along rows, texel centres at ``(i + 0.5) 2 / n - 1``).  Used by the GL filters of
:mod:`envcap.prefilter.fast` and :mod:`envcap.prefilter.composed`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["FACE_A", "FACE_B", "FACE_N", "LOOP_BUDGET", "footprint_rects", "footprint_theta", "loop_estimate"]

LOOP_BUDGET = 30000
"""Loop iterations one GL invocation may spend: Mesa llvmpipe ends a shader's loops after 65535
iterations in all (``docs/prefilter.md``)."""

FACE_N = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
FACE_A = np.array([[0, 0, -1], [0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0], [-1, 0, 0]], np.float64)
FACE_B = np.array([[0, -1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, -1, 0], [0, -1, 0]], np.float64)


def footprint_theta(w: float, eps: float) -> float:
    """Half-angle (radians) of the cap where ``cos^w >= eps`` (pi/2 for ``w = 0``)."""
    return math.pi / 2 if w == 0 else math.acos(min(1.0, eps ** (1.0 / w)))


def loop_estimate(theta: float, n: int) -> float:
    """Upper estimate of the loop iterations of one invocation over a cap of half-angle ``theta``
    on ``n``-texel faces: the rows visited plus the texels in the cap (texels are up to
    3^1.5 ~ 5.2x denser per steradian at face corners)."""
    cap = 2.0 * math.pi * (1.0 - math.cos(min(theta, math.pi)))
    texels = min(cap * 5.2 * (n / 2.0) ** 2, 6.0 * n * n)
    return texels + 6.0 * n


def footprint_rects(dirs: ArrayLike, theta: float, n_src: int) -> NDArray[np.int32]:
    """Texel rectangles per source face that hold every texel center within ``theta`` of each direction.

    ``dirs`` is ``(M, 3)`` unit directions, ``theta`` the cap half-angle (radians), ``n_src`` the
    source face size.  Returns ``(M, 6, 4)`` int32 ``(col0, col1, row0, row1)`` with exclusive
    ends (empty when ``col0 >= col1``).  float64 bounding box of the cap's projection on each face
    plane (an ellipse when the cap lies in front of the plane), widened by one texel; caps that
    reach behind a face plane get the whole face (only wide lobes, where sources are small).
    """
    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    m = d.shape[0]
    n = int(n_src)
    rects = np.zeros((m, 6, 4), dtype=np.int32)
    full = np.array([0, n, 0, n], dtype=np.int32)
    theta = float(min(max(theta, 0.0), math.pi)) * 1.0001 + 1e-9
    if theta >= 1.2:
        rects[:] = full
        return rects
    c, s = math.cos(theta), math.sin(theta)
    for f in range(6):
        dn, da, db = d @ FACE_N[f], d @ FACE_A[f], d @ FACE_B[f]
        ell = dn > s + 1e-9
        rest = ~ell & (dn > -s) & (2.0 * theta > math.asin(1.0 / math.sqrt(3.0)))
        rects[rest, f] = full
        if not ell.any():
            continue
        da_, db_, dn_ = da[ell], db[ell], dn[ell]
        A, B, C = da_**2 - c * c, 2 * da_ * db_, db_**2 - c * c
        D, E, F = 2 * da_ * dn_, 2 * db_ * dn_, dn_**2 - c * c

        def span(qa, qb, qc, center):
            disc = np.maximum(qb * qb - 4 * qa * qc, 0.0)
            r1 = (-qb - np.sqrt(disc)) / (2 * qa)
            r2 = (-qb + np.sqrt(disc)) / (2 * qa)
            lo, hi = np.minimum(r1, r2), np.maximum(r1, r2)
            return np.minimum(lo, center), np.maximum(hi, center)

        a_lo, a_hi = span(4 * A * C - B * B, 4 * C * D - 2 * B * E, 4 * C * F - E * E, da_ / dn_)
        b_lo, b_hi = span(4 * A * C - B * B, 4 * A * E - 2 * B * D, 4 * A * F - D * D, db_ / dn_)

        def idx(lo, hi):
            i0 = np.ceil((np.clip(lo, -1, 1) + 1) * 0.5 * n - 0.5) - 1
            i1 = np.floor((np.clip(hi, -1, 1) + 1) * 0.5 * n - 0.5) + 2
            return np.clip(i0, 0, n).astype(np.int32), np.clip(i1, 0, n).astype(np.int32)

        c0, c1 = idx(a_lo, a_hi)
        r0, r1 = idx(b_lo, b_hi)
        rects[ell, f] = np.stack([c0, c1, r0, r1], axis=1)
    return rects
