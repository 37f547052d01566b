"""The exact float64 reference of the cosine-lobe filter, and the solid-angle box pyramid.

Level ``k`` of a chain holds the environment averaged under the *normalized* lobe
``max(0, d.u)^w_k`` (``w_k`` from :class:`envcap.core.lobes.LobeLadder`)::

    m_k(d) = sum_u max(0, d.u)^w_k Omega(u) L(u) / sum_u max(0, d.u)^w_k Omega(u)

a solid-angle weighted average over all source texels ``u`` (texel-center quadrature with the
exact texel solid angles of :func:`envcap.core.cube.texel_solid_angles`, across face seams).  ``w = 0``
is the plain hemisphere average.  Cubes are ``(6, N, N, C)`` (any channel count; RGBA of a
street probe is filtered with the same weights, which keeps premultiplied alpha consistent).
Inputs with NaN or Inf texels are rejected with ``ValueError``.  This module computes ``m_k``
by brute force (the reference for tests, benchmarks and the evaluator's truth);
:mod:`envcap.prefilter.fast` is the GL filter a bake uses.  Derivation: ``docs/prefilter.md``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube as cube_geometry
from envcap.core.checks import unit_directions

__all__ = ["check_finite_cube", "check_cosine_power", "convolve_exact", "convolve_exact_dirs", "omega_box_pyramid"]


def check_finite_cube(cube: ArrayLike, name: str = "cube") -> NDArray[np.float64]:
    """Validate a ``(6, N, N, C)`` cube with finite values; return it as float64.

    Raises ``ValueError`` for a bad shape, and for NaN/Inf texels naming their count.
    """
    a = np.asarray(cube_geometry.check_cube(np.asarray(cube), name), dtype=np.float64)
    bad = ~np.isfinite(a)
    if bad.any():
        texels = int(np.count_nonzero(bad.any(axis=-1)))
        raise ValueError(f"{name} has {texels} texel(s) with NaN or Inf values ({int(bad.sum())} values); "
                         "clean the input (e.g. clamp the sun) before filtering")
    return a


def check_cosine_power(w: float) -> float:
    """``w`` as a float, finite and >= 0 (a cosine power of the lobe ``max(0, d.u)^w``)."""
    w = float(w)
    if math.isnan(w) or w < 0 or math.isinf(w):
        raise ValueError(f"cosine power w must be finite and >= 0, got {w!r}")
    return w


def convolve_exact_dirs(cube: ArrayLike, w: float, dirs: ArrayLike, chunk_elems: int = 1 << 22) -> NDArray[np.float64]:
    """Exact normalized ``cos^w`` average of ``cube`` at directions ``dirs`` (``(..., 3)``, any non-zero length).

    float64 brute force over every source texel (texel-center quadrature, exact solid angles),
    processed in chunks of about ``chunk_elems`` weights so memory stays bounded.  Weights are
    computed as ``exp(w (log cos - log cos_max))`` per output direction, so ``w = 1e7`` gives the
    nearest texel instead of 0/0.  Returns ``(..., C)`` float64.
    """
    a = check_finite_cube(cube)
    w = check_cosine_power(w)
    d = unit_directions(dirs, "dirs")
    out_shape = d.shape[:-1]
    d = d.reshape(-1, 3)
    n, c = a.shape[1], a.shape[3]
    src_dirs = cube_geometry.texel_directions(n).reshape(-1, 3)
    omega = cube_geometry.texel_solid_angles(n).reshape(-1)
    vals = a.reshape(-1, c) * omega[:, None]
    out = np.empty((d.shape[0], c), dtype=np.float64)
    step = max(1, chunk_elems // src_dirs.shape[0])
    for s0 in range(0, d.shape[0], step):
        cosv = d[s0:s0 + step] @ src_dirs.T
        pos = cosv > 0
        if w == 0:
            wt = pos.astype(np.float64)
        else:
            with np.errstate(divide="ignore"):
                lc = np.where(pos, np.log(np.where(pos, cosv, 1.0)), -np.inf)
            lc -= lc.max(axis=1, keepdims=True)
            wt = np.exp(w * lc)
        wt *= pos
        out[s0:s0 + step] = (wt @ vals) / (wt @ omega)[:, None]
    return out.reshape(out_shape + (c,))


def convolve_exact(cube: ArrayLike, w: float, out_size: int) -> NDArray[np.float64]:
    """Exact normalized ``cos^w`` filter of ``cube`` ``(6, N, N, C)`` onto a ``(6, M, M, C)`` cube.

    ``M = out_size``; output texels are evaluated at their GL texel-center directions.  Slow by
    design (``6 M^2 x 6 N^2`` weights): the reference for tests and benchmarks.
    """
    m = int(out_size)
    if m < 1:
        raise ValueError(f"out_size must be >= 1, got {out_size}")
    return convolve_exact_dirs(cube, w, cube_geometry.texel_directions(m))


def omega_box_pyramid(cube: ArrayLike, levels: int) -> list[NDArray[np.float64]]:
    """Solid-angle weighted 2x2 reductions: level ``j`` texel = exact mean of ``L`` over its solid angle.

    ``sum(Omega * L)`` is the same at every level (solid angles add up exactly).  Stops early at
    odd sizes.  Returns float64 arrays ``(6, N >> j, N >> j, C)``.
    """
    a = np.asarray(cube, dtype=np.float64)
    out = [a]
    n = a.shape[1]
    om = cube_geometry.texel_solid_angles(n)[..., None]
    wsum = a * om
    for _ in range(1, levels):
        if n % 2 or n < 2:
            break
        n //= 2
        wsum = wsum.reshape(6, n, 2, n, 2, -1).sum(axis=(2, 4))
        om = om.reshape(6, n, 2, n, 2, 1).sum(axis=(2, 4))
        out.append(wsum / om)
    return out
