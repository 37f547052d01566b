"""The fast cosine-lobe filter: a GLSL compute pass per level (``shaders/prefilter/prefilter_lobe.glsl``).

Computes the chain ``m_k`` defined in :mod:`envcap.prefilter.exact` (level 0 = the input, level
``k`` = the normalized ``cos^w_k`` average), approximated as follows: the source is the coarsest
solid-angle box reduction whose texels are small against the lobe, each coarse texel placed at its
luminance-weighted centroid direction; weights below a fraction of the peak are skipped
(:mod:`envcap.prefilter.footprint`); a few very bright texels (a sun, :mod:`envcap.prefilter.hot`) are summed
exactly at full resolution.
:data:`QUALITY` sets the trade-off.  Derivation and measured accuracy: ``docs/prefilter.md``.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from tqdm import tqdm

from envcap.core import cube as cube_geometry
from envcap.core.lobes import LobeLadder, lobe_ladder
from envcap.core.resources import shader_source
from envcap.gpu.context import create_context
from envcap.prefilter.composed import prefilter_many_composed
from envcap.prefilter.exact import check_cosine_power, check_finite_cube
from envcap.prefilter.footprint import LOOP_BUDGET, footprint_theta, loop_estimate
from envcap.prefilter.hot import hot_texels, luminance_weight

__all__ = ["QUALITIES", "QUALITY", "Quality", "prefilter_chain", "prefilter_many", "prefilter_level"]

# quality -> (q: source texels per lobe RMS angle, eps: footprint truncation (weights < eps * peak /
# dynamic range dropped), smallest source face size used).  Measured accuracy: docs/prefilter.md.
QUALITY: dict[str, tuple[float, float, int]] = {
    "fast": (4.0, 1e-3, 16),
    "default": (4.0, 1e-4, 32),
    "high": (8.0, 1e-9, 64),
}
class _Pyramid:
    """Source levels of one batch of cubes ``(P, 6, N, N, C)`` for the GL filter (float64, CPU).

    ``hot``: the level-0 texels brighter than :data:`~envcap.prefilter.hot.HOT_FACTOR` x the median positive luminance of
    their cube (at most :data:`~envcap.prefilter.hot.MAX_HOT` per cube, the brightest), kept as exact point samples and
    removed from the levels.  Level ``j``: ``s[j]`` ``(P, 6, n, n, C)`` sums of ``Omega * L``,
    ``om[j]`` ``(6, n, n)`` solid angles, ``dirs[j]`` ``(P, 6, n, n, 3)`` unit luminance-weighted
    centroid directions (texel centers at level 0).  ``dyn``: max / median luminance of what is
    left (footprint truncation is relative to it).
    """

    def __init__(self, a: NDArray[np.float64], levels: int) -> None:
        p, _, n, _, c = a.shape
        om0 = cube_geometry.texel_solid_angles(n)
        y = luminance_weight(a)
        self.hot_idx: list[NDArray[np.int64]] = []
        dyn = 1.0
        keep = np.ones(y.shape, bool)
        for i in range(p):
            yi = y[i].reshape(-1)
            cand, med = hot_texels(yi)
            self.hot_idx.append(cand)
            keep[i].reshape(-1)[cand] = False
            rest = yi[keep[i].reshape(-1)]
            if med > 0 and rest.size and rest.max() > 0:
                dyn = max(dyn, float(rest.max() / med))
        self.dyn = dyn
        d0 = cube_geometry.texel_directions(n)
        self.hot_dirs = [d0.reshape(-1, 3)[h] for h in self.hot_idx]
        self.hot_s = [(a[i] * om0[..., None]).reshape(-1, c)[h] for i, h in enumerate(self.hot_idx)]
        s = a * om0[None, ..., None] * keep[..., None]
        wgt = om0[None] * (np.where(keep, y, 0.0) + 1e-9 * max(float(y.max()), 1e-30))
        mom = wgt[..., None] * d0[None]
        self.s, self.om, self.dirs = [s], [om0], [np.broadcast_to(d0, (p,) + d0.shape)]
        om = om0
        for _ in range(1, levels):
            if n % 2 or n < 2:
                break
            n //= 2
            s = s.reshape(p, 6, n, 2, n, 2, c).sum(axis=(3, 5))
            om = om.reshape(6, n, 2, n, 2).sum(axis=(2, 4))
            wgt = wgt.reshape(p, 6, n, 2, n, 2).sum(axis=(3, 5))
            mom = mom.reshape(p, 6, n, 2, n, 2, 3).sum(axis=(3, 5))
            self.s.append(s)
            self.om.append(om)
            self.dirs.append(mom / np.linalg.norm(mom, axis=-1, keepdims=True))

    @property
    def sizes(self) -> list[int]:
        return [x.shape[2] for x in self.s]


def _source_level(w: float, theta: float, sizes: list[int], q: float, min_src: int) -> int:
    """The coarsest source level with texels at most ``1/q`` of the lobe's RMS angle
    (face-center texel ``2/N``), no coarser than ``min_src`` texels per face (or level 0), and
    whose footprint stays under :data:`LOOP_BUDGET` loop iterations (llvmpipe's loop limit)."""
    sigma = 1.0 / math.sqrt(w + 2.0)
    best = 0
    for j, nj in enumerate(sizes):
        if j and (nj < min_src or sigma < q * 2.0 / nj):
            break
        best = j
    while best + 1 < len(sizes) and loop_estimate(theta, sizes[best]) > LOOP_BUDGET:
        best += 1
    return best


class _GLFilter:
    def __init__(self, ctx: Any) -> None:
        self.ctx = ctx
        self.prog = ctx.compute_shader(shader_source("prefilter/prefilter_lobe.glsl"))

    def run(self, s4: NDArray[np.float64], dirs: NDArray[np.float64], om: NDArray[np.float64],
            hot_s: list[NDArray[np.float64]], hot_d: list[NDArray[np.float64]], n_out: int, w: float,
            eps: float, theta: float, n0: int) -> NDArray[np.float32]:
        """Filter one 4-channel block: ``s4`` ``(P, 6, n, n, 4)`` Omega * L, ``dirs`` ``(P, 6, n, n, 3)``,
        ``om`` ``(6, n, n)``; hot lists per probe.  Returns ``(P, 6, n_out, n_out, 4)`` float32."""
        ctx = self.ctx
        p, n = s4.shape[0], s4.shape[2]
        d4 = np.empty((p, 6, n, n, 4), np.float32)
        d4[..., :3] = dirs
        d4[..., 3] = om
        hs = np.concatenate([h for h in hot_s] + [np.zeros((1, 4))]).astype(np.float32)
        hd = np.concatenate([np.pad(h, ((0, 0), (0, 1))) for h in hot_d] + [np.zeros((1, 4))]).astype(np.float32)
        counts = np.array([h.shape[0] for h in hot_s], np.int32)
        hr = np.stack([np.concatenate([[0], np.cumsum(counts)[:-1]]), counts], 1).astype(np.int32)
        count = p * 6 * n_out * n_out
        bufs = [ctx.buffer(np.ascontiguousarray(s4, np.float32).tobytes()), ctx.buffer(d4.tobytes()),
                ctx.buffer(hs.tobytes()), ctx.buffer(hd.tobytes()), ctx.buffer(hr.tobytes()),
                ctx.buffer(reserve=count * 16)]
        try:
            for b, buf in enumerate(bufs):
                buf.bind_to_storage_buffer(b)
            full = theta >= 1.2
            pr = self.prog
            pr["count"].value = count
            pr["n_out"].value = n_out
            pr["n_src"].value = n
            pr["w"].value = float(w)
            pr["log_floor"].value = float(max(math.log(eps), -80.0)) if not full else -1e30
            pr["blur_var"].value = float((1.0 - (n / n0) ** 2) * (2.0 / n) ** 2 / 12.0)
            pr["theta"].value = float(theta)
            pr["cos_theta"].value = float(math.cos(theta))
            pr["full"].value = full
            groups = (count + 63) // 64
            gx = min(groups, 1024)
            pr.run(group_x=gx, group_y=(groups + gx - 1) // gx)
            out = np.frombuffer(bufs[5].read(), dtype=np.float32).reshape(p, 6, n_out, n_out, 4).copy()
        finally:
            for buf in bufs:
                buf.release()
        bad = ~np.isfinite(out).all(axis=-1)
        if bad.any():  # every weight underflowed (lobe << one source texel): the nearest texel, w -> inf
            pi, f, r, c = np.nonzero(bad)
            d = cube_geometry.face_uv_to_direction(f, (c + 0.5) * 2.0 / n_out - 1.0, (r + 0.5) * 2.0 / n_out - 1.0)
            ff, rr, cc = cube_geometry.direction_to_texel(d, n)
            out[pi, f, r, c] = (s4[pi, ff, rr, cc] / om[ff, rr, cc, None]).astype(np.float32)
        return out

    def release(self) -> None:
        self.prog.release()


Quality = Literal["fast", "default", "high", "composed"]
QUALITIES: tuple[str, ...] = (*QUALITY, "composed")
"""Every ``quality`` the chain filters accept: the coarse-source filter's settings (:data:`QUALITY`)
and ``"composed"`` (:mod:`envcap.prefilter.composed`)."""


def prefilter_many(cubes: ArrayLike, ladder: LobeLadder | None = None, quality: Quality = "default",
                   ctx: Any = None, progress: bool | None = None,
                   batch_bytes: int = 64 << 20, out: list[NDArray[np.float32]] | None = None) -> list[NDArray[np.float32]]:
    """Filter ``P`` cubes ``(P, 6, N, N, C)`` into cosine-lobe chains: a list of ``(P, 6, N_k, N_k, C)``.

    Same result as :func:`prefilter_chain` on each cube (one GL dispatch per level and channel
    block for a batch of probes whose source buffers fit ``batch_bytes``), the form a probe-set
    bake wants: level ``k`` of all probes is one array, ready for a cube-map array.
    ``quality="composed"`` filters each level from an earlier one with the difference lobe
    (:func:`envcap.prefilter.composed.prefilter_many_composed`); it reads float32 cubes as they
    are (no float64 copy; the same result as their float64 copy).  ``out``: float32 arrays of
    those shapes to fill and return (``out[0]`` may be ``cubes`` itself: then it is not copied).
    """
    a = np.asarray(cubes)
    if a.ndim != 5:
        raise ValueError(f"cubes must have shape (P, 6, N, N, C), got {a.shape}")
    if a.shape[0] < 1:
        raise ValueError("cubes must hold at least one cube (P >= 1)")
    if a.shape[1] != 6 or a.shape[2] != a.shape[3] or a.shape[2] < 1 or a.shape[4] < 1:
        raise ValueError(f"cubes must have shape (P, 6, N, N, C), got {a.shape}")
    if quality == "composed" and a.dtype in (np.float32, np.float64):
        if not all(np.isfinite(c).all() for c in a):   # (per cube: a small temporary) name the first bad cube
            for i, c in enumerate(a):
                check_finite_cube(c, f"cube {i}" if a.shape[0] > 1 else "cube")
    else:
        a = np.stack([check_finite_cube(c, f"cube {i}") for i, c in enumerate(a)]) if a.shape[0] > 1 \
            else check_finite_cube(a[0])[None]
    p_all, _, n, _, nch = a.shape
    if ladder is None:
        ladder = lobe_ladder(n)
    if ladder.sizes[0] != n:
        raise ValueError(f"ladder is for {ladder.sizes[0]}-texel faces, cube has {n}")
    if quality not in QUALITIES:
        raise ValueError(f"quality must be one of {sorted(QUALITIES)}, got {quality!r}")
    if quality == "composed":
        own = ctx is None
        if own:
            ctx = create_context()
        try:
            return prefilter_many_composed(a, ladder, ctx, progress, batch_bytes, out=out)
        finally:
            if own:
                ctx.release()
    q, eps0, min_src = QUALITY[quality]
    chain = [np.empty((p_all, 6, s, s, nch), np.float32) for s in ladder.sizes] if out is None else list(out)
    if [x.shape for x in chain] != [(p_all, 6, s, s, nch) for s in ladder.sizes] or any(x.dtype != np.float32 for x in chain):
        raise ValueError(f"out must be float32 arrays of the chain's shapes {[(p_all, 6, s, s, nch) for s in ladder.sizes]}")
    if chain[0] is not cubes:
        chain[0][:] = a
    if ladder.levels == 1:
        return chain
    own = ctx is None
    if own:
        ctx = create_context()
    filt = _GLFilter(ctx)
    per = max(1, int(batch_bytes // (6 * n * n * 16)))
    try:
        bar = tqdm(total=p_all * (ladder.levels - 1), desc="prefilter", unit="level",
                   disable=None if progress is None else not progress)
        for b0 in range(0, p_all, per):
            batch = a[b0:b0 + per]
            pyr = _Pyramid(batch, ladder.levels)
            eps = eps0 / max(pyr.dyn, 1.0)
            for k in range(1, ladder.levels):
                w = float(ladder.powers[k])
                theta = footprint_theta(w, eps)
                j = _source_level(w, theta, pyr.sizes, q, min_src)
                for c0 in range(0, nch, 4):
                    cc = min(4, nch - c0)
                    s4 = np.zeros(pyr.s[j].shape[:-1] + (4,), np.float64)
                    s4[..., :cc] = pyr.s[j][..., c0:c0 + cc]
                    hs = [np.pad(h[:, c0:c0 + cc], ((0, 0), (0, 4 - cc))) for h in pyr.hot_s]
                    res = filt.run(s4, pyr.dirs[j], pyr.om[j], hs, pyr.hot_dirs, ladder.sizes[k], w, eps, theta, n)
                    chain[k][b0:b0 + per, ..., c0:c0 + cc] = res[..., :cc]
                bar.update(batch.shape[0])
        bar.close()
    finally:
        filt.release()
        if own:
            ctx.release()
    return chain


def prefilter_level(cube: ArrayLike, w: float, out_size: int, quality: Quality = "default",
                    ctx: Any = None) -> NDArray[np.float32]:
    """One normalized ``cos^w`` level of ``cube`` ``(6, N, N, C)`` on a ``(6, M, M, C)`` grid
    (``M = out_size``, any ``w >= 0``), by the same GL filter as :func:`prefilter_chain`.

    For chains built on other ladders (e.g. the cmft comparison in ``envcap bench zw``).
    ``quality``: one of :data:`QUALITY` (``"composed"`` needs the levels before: chains only).
    """
    a = check_finite_cube(cube)
    w = check_cosine_power(w)
    m = int(out_size)
    if m < 1:
        raise ValueError(f"out_size must be >= 1, got {out_size}")
    if quality not in QUALITY:
        raise ValueError(f"quality must be one of {sorted(QUALITY)}, got {quality!r}")
    q, eps0, min_src = QUALITY[quality]
    own = ctx is None
    if own:
        ctx = create_context()
    filt = _GLFilter(ctx)
    try:
        n, nch = a.shape[1], a.shape[3]
        pyr = _Pyramid(a[None], n.bit_length())
        eps = eps0 / max(pyr.dyn, 1.0)
        theta = footprint_theta(w, eps)
        j = _source_level(w, theta, pyr.sizes, q, min_src)
        out = np.empty((6, m, m, nch), np.float32)
        for c0 in range(0, nch, 4):
            cc = min(4, nch - c0)
            s4 = np.zeros(pyr.s[j].shape[:-1] + (4,), np.float64)
            s4[..., :cc] = pyr.s[j][..., c0:c0 + cc]
            hs = [np.pad(h[:, c0:c0 + cc], ((0, 0), (0, 4 - cc))) for h in pyr.hot_s]
            out[..., c0:c0 + cc] = filt.run(s4, pyr.dirs[j], pyr.om[j], hs, pyr.hot_dirs, m, w, eps, theta, n)[0, ..., :cc]
    finally:
        filt.release()
        if own:
            ctx.release()
    return out


def prefilter_chain(cube: ArrayLike, ladder: LobeLadder | None = None, quality: Quality = "default",
                    ctx: Any = None, progress: bool | None = None) -> list[NDArray[np.float32]]:
    """Filter ``cube`` ``(6, N, N, C)`` into a cosine-lobe mip chain ``[(6, N_k, N_k, C)]`` (float32).

    Level 0 is the input (unfiltered, as float32).  Level ``k >= 1`` is the normalized
    ``cos^w_k`` average (``ladder`` defaults to :func:`envcap.core.lobes.lobe_ladder`), computed by a
    GLSL compute pass (one dispatch per level) from the coarsest solid-angle box reduction of the
    input whose texels are at most ``1/q`` of the lobe's RMS angle, each coarse texel placed at
    its luminance-weighted centroid direction, over the footprint where
    ``cos^w >= eps / D * peak`` (``D``: dynamic range left after the hot texels; ``quality``:
    ``(q, eps, min source size)`` in :data:`QUALITY`).  The few texels brighter than
    :data:`~envcap.prefilter.hot.HOT_FACTOR` x the median (a sun) are summed exactly at full resolution.
    ``ctx``: a moderngl context (one is created and released when ``None``).  ``progress``:
    tqdm bar (``None``: only on a TTY).  Accuracy and speed: ``docs/prefilter.md``.
    """
    a = check_finite_cube(cube)
    return [lv[0] for lv in prefilter_many(a[None], ladder, quality, ctx, progress)]
