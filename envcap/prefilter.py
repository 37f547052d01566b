"""Cosine-lobe mip chains: an exact float64 reference and a fast GLSL filter.

Level ``k`` of a chain holds the environment averaged under the *normalized* lobe
``max(0, d.u)^w_k`` (``w_k`` from :class:`envcap.lobes.LobeLadder`)::

    m_k(d) = sum_u max(0, d.u)^w_k Omega(u) L(u) / sum_u max(0, d.u)^w_k Omega(u)

a solid-angle weighted average over all source texels ``u`` (texel-center quadrature with the
exact texel solid angles of :func:`envcap.cube.texel_solid_angles`, across face seams).  ``w = 0``
is the plain hemisphere average.  Cubes are ``(6, N, N, C)`` (any channel count; RGBA of a
street probe is filtered with the same weights, which keeps premultiplied alpha consistent).
Inputs with NaN or Inf texels are rejected with ``ValueError``.  Derivation and measured
accuracy: ``docs/prefilter.md``.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap import cube as cubemod
from envcap.lobes import LobeLadder, lobe_ladder

__all__ = [
    "check_finite_cube",
    "convolve_exact",
    "convolve_exact_dirs",
    "omega_box_pyramid",
    "footprint_rects",
    "prefilter_chain",
    "QUALITY",
]

# quality -> (min lobe RMS angle in source texels, footprint truncation: weights < eps * peak dropped)
QUALITY: dict[str, tuple[float, float]] = {
    "fast": (4.0, 1e-4),
    "default": (math.inf, 1e-6),
    "high": (math.inf, 1e-10),
}

# Face frames of envcap.cube: direction = N + u A + v B.
_FN = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
_FA = np.array([[0, 0, -1], [0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0], [-1, 0, 0]], np.float64)
_FB = np.array([[0, -1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, -1, 0], [0, -1, 0]], np.float64)


def check_finite_cube(cube: ArrayLike, name: str = "cube") -> NDArray[np.float64]:
    """Validate a ``(6, N, N, C)`` cube with finite values; return it as float64.

    Raises ``ValueError`` for a bad shape, and for NaN/Inf texels naming their count.
    """
    a = cubemod.check_cube(np.asarray(cube), name)
    if a.ndim != 4:
        raise ValueError(f"{name} must have shape (6, N, N, C), got {a.shape}")
    a = np.asarray(a, dtype=np.float64)
    bad = ~np.isfinite(a)
    if bad.any():
        texels = int(np.count_nonzero(bad.any(axis=-1)))
        raise ValueError(f"{name} has {texels} texel(s) with NaN or Inf values ({int(bad.sum())} values); "
                         "clean the input (e.g. clamp the sun) before filtering")
    return a


def _check_w(w: float) -> float:
    w = float(w)
    if math.isnan(w) or w < 0 or math.isinf(w):
        raise ValueError(f"cosine power w must be finite and >= 0, got {w!r}")
    return w


def convolve_exact_dirs(cube: ArrayLike, w: float, dirs: ArrayLike, chunk_elems: int = 1 << 22) -> NDArray[np.float64]:
    """Exact normalized ``cos^w`` average of ``cube`` at unit directions ``dirs`` (``(..., 3)``).

    float64 brute force over every source texel (texel-center quadrature, exact solid angles),
    processed in chunks of about ``chunk_elems`` weights so memory stays bounded.  Weights are
    computed as ``exp(w (log cos - log cos_max))`` per output direction, so ``w = 1e7`` gives the
    nearest texel instead of 0/0.  Returns ``(..., C)`` float64.
    """
    a = check_finite_cube(cube)
    w = _check_w(w)
    d = np.asarray(dirs, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"dirs must have shape (..., 3), got {d.shape}")
    out_shape = d.shape[:-1]
    d = d.reshape(-1, 3)
    norm = np.linalg.norm(d, axis=1)
    if not np.all(np.isfinite(norm)) or np.any(norm == 0):
        raise ValueError("dirs must be finite and non-zero")
    d = d / norm[:, None]
    n, c = a.shape[1], a.shape[3]
    src_dirs = cubemod.texel_directions(n).reshape(-1, 3)
    omega = cubemod.texel_solid_angles(n).reshape(-1)
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
    return convolve_exact_dirs(cube, w, cubemod.texel_directions(m))


def omega_box_pyramid(cube: ArrayLike, levels: int) -> list[NDArray[np.float64]]:
    """Solid-angle weighted 2x2 reductions: level ``j`` texel = exact mean of ``L`` over its solid angle.

    ``sum(Omega * L)`` is the same at every level (solid angles add up exactly).  Stops early at
    odd sizes.  Returns float64 arrays ``(6, N >> j, N >> j, C)``.
    """
    a = np.asarray(cube, dtype=np.float64)
    out = [a]
    n = a.shape[1]
    om = cubemod.texel_solid_angles(n)[..., None]
    wsum = a * om
    for _ in range(1, levels):
        if n % 2 or n < 2:
            break
        n //= 2
        wsum = wsum.reshape(6, n, 2, n, 2, -1).sum(axis=(2, 4))
        om = om.reshape(6, n, 2, n, 2, 1).sum(axis=(2, 4))
        out.append(wsum / om)
    return out


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
        dn, da, db = d @ _FN[f], d @ _FA[f], d @ _FB[f]
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


def _source_level(sigma: float, sizes: tuple[int, ...], avail: int, min_sigma_texels: float) -> int:
    """Coarsest available level whose face-center texel angle (2/N) is <= sigma / min_sigma_texels."""
    best = 0
    for j in range(avail):
        if sigma >= min_sigma_texels * 2.0 / sizes[j]:
            best = j
    return best


class _GLFilter:
    MAX_LOOP = 32768  # llvmpipe ends loops after 65535 iterations: stay well below per dispatch

    def __init__(self, ctx: Any) -> None:
        from envcap.resources import shader_source

        self.ctx = ctx
        self.prog = ctx.compute_shader(shader_source("prefilter_lobe.glsl"))

    def run(self, src_omega_l: NDArray[np.float32], omega: NDArray[np.float32], dirs: NDArray[np.float32],
            rects: NDArray[np.int32], w: float, log_floor: float, offset: float) -> NDArray[np.float32]:
        ctx = self.ctx
        m = dirs.shape[0]
        n_src = src_omega_l.shape[1]
        bufs = [
            ctx.buffer(np.ascontiguousarray(src_omega_l, np.float32).tobytes()),
            ctx.buffer(np.ascontiguousarray(omega, np.float32).tobytes()),
            ctx.buffer(np.ascontiguousarray(np.concatenate([dirs, np.zeros((m, 1), np.float32)], 1)).tobytes()),
            ctx.buffer(np.ascontiguousarray(rects, np.int32).tobytes()),
            ctx.buffer(reserve=m * 48),
        ]
        acc = np.zeros((m, 4), np.float64)
        wsum = np.zeros(m, np.float64)
        best = np.full(m, -np.inf)
        best_val = np.zeros((m, 4), np.float64)
        # rows of the 6 faces, stacked: face f row j is f * n_src + j
        rows_lo = (rects[:, :, 2] + np.arange(6) * n_src)[rects[:, :, 0] < rects[:, :, 1]]
        rows_hi = (rects[:, :, 3] + np.arange(6) * n_src)[rects[:, :, 0] < rects[:, :, 1]]
        band = max(1, self.MAX_LOOP // (n_src + 1))
        try:
            for b, buf in enumerate(bufs):
                buf.bind_to_storage_buffer(b)
            self.prog["count"].value = m
            self.prog["n_src"].value = n_src
            self.prog["w"].value = float(w)
            self.prog["log_floor"].value = float(log_floor)
            self.prog["offset"].value = float(offset)
            for r0 in range(0, 6 * n_src, band):
                r1 = min(r0 + band, 6 * n_src)
                if not np.any((rows_lo < r1) & (rows_hi > r0)):
                    continue
                self.prog["row_begin"].value = r0
                self.prog["row_end"].value = r1
                self.prog.run(group_x=(m + 63) // 64)
                part = np.frombuffer(bufs[4].read(), dtype=np.float32).reshape(m, 3, 4)
                acc += part[:, 0]
                wsum += part[:, 1, 0]
                better = part[:, 1, 1] > best
                best = np.where(better, part[:, 1, 1], best)
                best_val[better] = part[better, 2]
        finally:
            for buf in bufs:
                buf.release()
        ok = wsum > 0
        out = best_val.copy()
        out[ok] = acc[ok] / wsum[ok, None]
        return out.astype(np.float32)

    def release(self) -> None:
        self.prog.release()


Quality = Literal["fast", "default", "high"]


def prefilter_chain(cube: ArrayLike, ladder: LobeLadder | None = None, quality: Quality = "default",
                    ctx: Any = None, progress: bool | None = None) -> list[NDArray[np.float32]]:
    """Filter ``cube`` ``(6, N, N, C)`` into a cosine-lobe mip chain ``[(6, N_k, N_k, C)]`` (float32).

    Level 0 is the input (unfiltered, as float32).  Level ``k >= 1`` is the normalized
    ``cos^w_k`` average (``ladder`` defaults to :func:`envcap.lobes.lobe_ladder`), computed with a
    GLSL compute pass from the coarsest solid-angle box reduction of the input whose texels are at
    most ``1/q`` of the lobe's RMS angle, over the footprint where ``cos^w >= eps * peak``
    (``quality``: ``(q, eps)`` in :data:`QUALITY`).  ``ctx``: a moderngl context (one is created
    and released when ``None``).  ``progress``: tqdm bar (``None``: only on a TTY).
    """
    from tqdm import tqdm

    a = check_finite_cube(cube)
    n, nch = a.shape[1], a.shape[3]
    if ladder is None:
        ladder = lobe_ladder(n)
    if ladder.sizes[0] != n:
        raise ValueError(f"ladder is for {ladder.sizes[0]}-texel faces, cube has {n}")
    if quality not in QUALITY:
        raise ValueError(f"quality must be one of {sorted(QUALITY)}, got {quality!r}")
    min_sigma_texels, eps = QUALITY[quality]
    pyramid = omega_box_pyramid(a, ladder.levels)
    # Truncate the footprint relative to the dynamic range, not only to the lobe peak: a 1e9 sun
    # next to a 1e3 sky must not vanish at the edge of its footprint.
    mag = np.abs(a).max(axis=-1)
    pos = mag[mag > 0]
    dyn = float(pos.max() / np.median(pos)) if pos.size else 1.0
    eps = eps / max(dyn, 1.0)
    chain: list[NDArray[np.float32]] = [a.astype(np.float32)]
    if ladder.levels == 1:
        return chain
    own = ctx is None
    if own:
        from envcap.gl import create_context

        ctx = create_context()
    filt = _GLFilter(ctx)
    try:
        for k in tqdm(range(1, ladder.levels), desc="prefilter", unit="level", disable=None if progress is None else not progress):
            w = float(ladder.powers[k])
            nk = ladder.sizes[k]
            sigma = 1.0 / math.sqrt(w + 2.0)
            j = _source_level(sigma, ladder.sizes, len(pyramid), min_sigma_texels)
            src = pyramid[j]
            ns = src.shape[1]
            om = cubemod.texel_solid_angles(ns)
            dirs = cubemod.texel_directions(nk).reshape(-1, 3)
            theta = math.pi if w == 0 else math.acos(min(1.0, eps ** (1.0 / w)))
            rects = footprint_rects(dirs, theta, ns)
            offset = min(w / (ns * ns), 60.0)
            out = np.empty((dirs.shape[0], nch), np.float32)
            for c0 in range(0, nch, 4):
                cc = min(4, nch - c0)
                s4 = np.zeros((6, ns, ns, 4), np.float64)
                s4[..., :cc] = src[..., c0:c0 + cc] * om[..., None]
                res = filt.run(s4.astype(np.float32), om[0].astype(np.float32), dirs.astype(np.float32), rects, w,
                               math.log(eps), offset)
                out[:, c0:c0 + cc] = res[:, :cc]
            chain.append(out.reshape(6, nk, nk, nch))
    finally:
        filt.release()
        if own:
            ctx.release()
    return chain
