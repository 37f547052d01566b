"""The composed cosine-lobe filter (``quality="composed"``): level ``k`` filtered from an already
filtered level with the difference lobe (``shaders/prefilter/prefilter_composed.glsl``).

Computes the chain ``m_k`` defined in :mod:`envcap.prefilter.exact`.  The hot texels (a sun,
:mod:`envcap.prefilter.hot`) are removed from the input first; the rest ("cold") is filtered
level by level as :func:`envcap.prefilter.composition.composition_plan` says (level 1 directly
from the input, most others from an earlier cold level with the difference lobe), on the GL
context, without reading levels back between passes; every level then adds the hot texels
exactly, with its own lobe and the exact level-0 normalizer (carried through the passes as
``nu``).  Only the luminance channels of a hot texel (RGB; all channels when ``C < 3``) are split
off; alpha stays in the source, so a constant alpha stays constant.  A probe's result does not
depend on the other probes of its batch (bit for bit).  Derivation and measured accuracy:
``docs/prefilter.md``.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from envcap.core import cube as cube_geometry
from envcap.core.lobes import LobeLadder
from envcap.core.resources import shader_source
from envcap.prefilter.composition import COMPOSED_EPS, LevelStep, composition_plan, truncated_power
from envcap.prefilter.footprint import footprint_theta
from envcap.prefilter.hot import hot_texels, luminance_weight

__all__ = ["PROBES_PER_INVOCATION", "prefilter_many_composed"]

PROBES_PER_INVOCATION = 4
"""Probes of a batch filtered by one GL invocation: the weights of an output texel are computed
once and applied to each (the footprint and the lobe do not depend on the probe)."""


class _ComposedGL:
    """The composed-pass programs (one per (direct, taylor, probes per invocation) variant, compiled
    on first use) and the per-size solid-angle tables on one context."""

    def __init__(self, ctx: Any) -> None:
        self.ctx = ctx
        self.source = shader_source("prefilter/prefilter_composed.glsl")
        self.progs: dict[tuple[bool, bool, int], Any] = {}
        self.om: dict[int, Any] = {}
        self.seconds: dict[int, list[float]] | None = None   # level -> [wall s, CPU s] when timed
        self.bufs: dict[str, Any] = {}
        self.host = np.empty(0, np.float32)

    def program(self, direct: bool, taylor: bool, probes: int) -> Any:
        key = (direct, taylor, probes)
        if key not in self.progs:
            head, rest = self.source.split("\n", 1)   # the #version line, then the defines
            defines = f"#define DIRECT {int(direct)}\n#define TAYLOR {int(taylor)}\n#define PROBES {probes}\n"
            self.progs[key] = self.ctx.compute_shader(f"{head}\n{defines}{rest}")
        return self.progs[key]

    def omega(self, n: int) -> Any:
        if n not in self.om:
            self.om[n] = self.ctx.buffer(cube_geometry.texel_solid_angles(n)[0].astype(np.float32).tobytes())
        return self.om[n]

    def scratch(self, name: str, nbytes: int) -> Any:
        """GL buffer ``name`` of at least ``nbytes``, kept for the whole call: every batch reuses it
        (fresh memory costs its page faults each time: ~1.4 ms of CPU per MB on this machine)."""
        b = self.bufs.get(name)
        if b is None or b.size < nbytes:
            if b is not None:
                b.release()
            b = self.bufs[name] = self.ctx.buffer(reserve=nbytes)
        return b

    def host_array(self, shape: tuple[int, ...]) -> NDArray[np.float32]:
        """A float32 array of ``shape`` on memory kept for the whole call (as :meth:`scratch`)."""
        size = math.prod(shape)
        if self.host.size < size:
            self.host = np.empty(size, np.float32)
        return self.host[:size].reshape(shape)

    def release(self) -> None:
        for b in [*self.om.values(), *self.bufs.values()]:
            b.release()
        for pr in self.progs.values():
            pr.release()


def _run_level(gl: _ComposedGL, src: Any, src_nu: Any, n_src: int, hot: tuple[Any, Any, Any], p: int, n_out: int,
               step: LevelStep, w_level: float) -> tuple[Any, Any, Any]:
    """One dispatch; returns the (cold, nu, total) buffers of the level (``gl``'s scratch buffers, at
    least): cold ``(6, n_out, n_out, p)`` vec4 (as ``src``), total ``(p, 6, n_out, n_out)`` vec4 (one
    buffer for every level: read it before the next), nu ``(6, n_out, n_out)`` float."""
    ctx = gl.ctx
    group = min(p, PROBES_PER_INVOCATION)
    count = -(-p // group) * 6 * n_out * n_out
    theta = footprint_theta(step.lobe, COMPOSED_EPS)
    full = theta >= 1.2
    wp, c = (step.lobe, 0.0) if full else truncated_power(step.lobe, COMPOSED_EPS)
    trunc_mass = 0.0 if full else COMPOSED_EPS * c
    nu_scale = (wp + 1.0) / (2.0 * math.pi * (1.0 - trunc_mass))
    taylor = step.taylor
    offset = min(4.0 * wp / (n_src * n_src), 60.0)
    texels = p * 6 * n_out * n_out
    cold, nu = gl.scratch(f"cold{step.level}", texels * 16), gl.scratch(f"nu{step.level}", 6 * n_out * n_out * 4)
    total = gl.scratch("total", texels * 16)
    for b, buf in enumerate((src, src_nu, gl.omega(n_src), *hot, cold, nu, total)):
        buf.bind_to_storage_buffer(b)
    pr = gl.program(step.source == 0, taylor, group)
    uniforms = {
        "count": count, "probes": p, "n_out": n_out, "n_src": n_src, "w_lobe": float(wp), "eps": 0.0 if full else COMPOSED_EPS,
        "theta": float(theta), "cos_theta": float(math.cos(theta)), "full": full, "offset": float(offset),
        "wsum_scale": float(nu_scale * ((2.0 / n_src) ** 2 if taylor else math.exp(-offset))),
        "w_level": float(w_level), "hot_norm": float((w_level + 1.0) / (2.0 * math.pi)),
    }
    for name, value in uniforms.items():
        member = pr.get(name, None)   # a variant may not use every uniform
        if member is not None:
            member.value = value
    groups = (count + 63) // 64
    gx = min(groups, 1024)
    pr.run(group_x=gx, group_y=(groups + gx - 1) // gx)
    return cold, nu, total


def _nearest_average(level0: NDArray, pi: NDArray[np.int64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """The ``w -> infinity`` limit of the normalized lobe at unit directions ``d`` ``(M, 3)`` on the
    cubes ``level0[pi]`` ``(M, 6, N, N, C)``: the angularly nearest texel centre, or the average of
    the equally near ones (searched in the 3 x 3 texels around the texel holding ``d``)."""
    n = level0.shape[2]
    f, r, c = cube_geometry.direction_to_texel(d, n)
    rr = np.clip(r[:, None] + np.repeat(np.arange(-1, 2), 3)[None], 0, n - 1)
    cc = np.clip(c[:, None] + np.tile(np.arange(-1, 2), 3)[None], 0, n - 1)
    ff = np.broadcast_to(f[:, None], rr.shape)
    cand = cube_geometry.face_uv_to_direction(ff, (cc + 0.5) * 2.0 / n - 1.0, (rr + 0.5) * 2.0 / n - 1.0)
    cos = np.einsum("mkc,mc->mk", cand, d) / np.linalg.norm(cand, axis=-1)
    near = cos >= cos.max(axis=1, keepdims=True) - 1e-12
    vals = level0[pi[:, None], ff, rr, cc].astype(np.float64)   # (M, 9, C)
    return (vals * near[..., None]).sum(axis=1) / near.sum(axis=1, keepdims=True)


def _nearest_fill(out: NDArray[np.float32], level0: NDArray[np.float64], cold0: NDArray[np.float32], cold: Any,
                  nu: Any) -> NDArray[np.float32]:
    """``out`` ``(P, 6, M, M, 4)`` with its non-finite texels (a direct pass whose every weight
    underflowed: the lobe is far below a texel) replaced by the ``w -> infinity`` limit on
    ``level0`` ``(P, 6, N, N, cc)``; the level's cold and nu buffers get the same limit on
    ``cold0`` ``(P, 6, N, N, 4)`` and 1, so later levels composed from it see the same texels."""
    out = out.copy()
    bad = ~np.isfinite(out).all(axis=-1)
    m, cc = out.shape[2], level0.shape[-1]
    pi, f, r, c = np.nonzero(bad)
    d = cube_geometry.face_uv_to_direction(f, (c + 0.5) * 2.0 / m - 1.0, (r + 0.5) * 2.0 / m - 1.0)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    out[pi, f, r, c] = 0.0
    out[pi, f, r, c, :cc] = _nearest_average(level0, pi, d)
    cold_a = np.frombuffer(cold.read(size=out.size * 4), np.float32).reshape(out.shape[1:4] + (out.shape[0], 4)).copy()
    nu_a = np.frombuffer(nu.read(size=int(np.prod(out.shape[1:-1])) * 4),
                         np.float32).reshape(out.shape[1:-1]).copy()
    cold_a[f, r, c, pi] = _nearest_average(cold0, pi, d)
    nu_a[bad.any(axis=0)] = 1.0
    cold.write(cold_a.tobytes())
    nu.write(nu_a.tobytes())
    return out


class _HotTexels:
    """The hot texels of a batch ``(P, 6, N, N, C)`` float64, as the shader reads them.

    ``batch`` float32 or float64.  ``probe``, ``index``: probe and flat texel index of each; ``dirs`` ``(H + 1, 4)`` float32 unit
    directions (one padding row); ``ranges`` ``(P, 2)`` int32 first hot texel and count per probe;
    ``values`` ``(H, C)`` float64 ``Omega * L`` of the luminance channels (RGB; every channel when
    ``C < 3``) and 0 in the others (alpha stays in the source, so a constant alpha stays constant);
    ``lum``: the number of luminance channels.
    """

    def __init__(self, batch: NDArray[np.floating]) -> None:
        p, _, n, _, nch = batch.shape
        # per probe, in float64 (the values of a float32 batch exactly): no float64 copy of the batch
        per_probe = [hot_texels(luminance_weight(np.asarray(batch[i], np.float64)))[0] for i in range(p)]
        self.index = np.concatenate(per_probe)
        self.probe = np.repeat(np.arange(p), [h.size for h in per_probe])
        face, rem = np.divmod(self.index, n * n)
        row, col = np.divmod(rem, n)
        dirs = cube_geometry.face_uv_to_direction(face, (col + 0.5) * 2.0 / n - 1.0, (row + 0.5) * 2.0 / n - 1.0)
        dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
        self.dirs = np.concatenate([np.pad(dirs, ((0, 0), (0, 1))), np.zeros((1, 4))]).astype(np.float32)
        counts = np.array([h.size for h in per_probe], np.int32)
        self.ranges = np.stack([np.concatenate([[0], np.cumsum(counts)[:-1]]), counts], 1).astype(np.int32)
        self.lum = 3 if nch >= 3 else nch
        self.values = (batch.reshape(p, -1, nch)[self.probe, self.index].astype(np.float64)
                       * cube_geometry.texel_solid_angle(row, col, n)[:, None])
        self.values[:, self.lum:] = 0.0


def _filter_block(gl: _ComposedGL, batch: NDArray[np.floating], hot: _HotTexels, c0: int, ladder: LobeLadder,
                  steps: list[LevelStep], ones: Any, out: list[NDArray[np.float32]], b0: int) -> None:
    """Filter channels ``c0 .. c0 + 3`` of ``batch`` into ``out[k][b0:b0 + P]`` for every step."""
    ctx = gl.ctx
    p, _, n, _, nch = batch.shape
    cc = min(4, nch - c0)
    # the source holds the probes of a texel next to each other: (6, N, N, P, 4), made in one copy
    src = gl.host_array((6, n, n, p, 4))
    src[..., :cc] = np.moveaxis(batch[..., c0:c0 + cc], 0, 3)
    src[..., cc:] = 0.0
    face, rem = np.divmod(hot.index, n * n)
    src[face, rem // n, rem % n, hot.probe, :max(0, min(4, hot.lum - c0))] = 0.0   # the hot texels leave the source
    hot_s = np.zeros((hot.index.size + 1, 4), np.float32)
    hot_s[:-1, :cc] = hot.values[:, c0:c0 + cc]
    hot_bufs = (ctx.buffer(hot_s), ctx.buffer(hot.dirs), ctx.buffer(hot.ranges))
    src_gl = gl.scratch("src", src.nbytes)
    src_gl.write(src)
    levels: dict[int, tuple[Any, Any]] = {0: (src_gl, ones)}
    try:
        for step in steps:
            k, m = step.level, ladder.sizes[step.level]
            src_buf, src_nu = levels[step.source]
            if gl.seconds is not None:
                ctx.finish()
                t0, cpu0 = time.perf_counter(), time.process_time()
            cold, nu, total = _run_level(gl, src_buf, src_nu, ladder.sizes[step.source], hot_bufs, p, m, step,
                                         float(ladder.powers[k]))
            if gl.seconds is not None:
                ctx.finish()
                acc = gl.seconds.setdefault(k, [0.0, 0.0])
                acc[0] += time.perf_counter() - t0
                acc[1] += time.process_time() - cpu0
            levels[k] = (cold, nu)
            dest = out[k][b0:b0 + p]
            if cc == 4 == nch and dest.flags.c_contiguous:
                total.read_into(dest, size=dest.nbytes)   # straight into the chain: no copy
                res = dest
            else:
                res = np.frombuffer(total.read(size=p * 6 * m * m * 16), np.float32).reshape(p, 6, m, m, 4)
            if step.source == 0 and not np.isfinite(res).all():
                res = _nearest_fill(res, batch[..., c0:c0 + cc], np.moveaxis(src, 3, 0), cold, nu)
            if res is not dest:
                dest[..., c0:c0 + cc] = res[..., :cc]
    finally:
        for buf in hot_bufs:
            buf.release()


def prefilter_many_composed(a: NDArray[np.floating], ladder: LobeLadder, ctx: Any, progress: bool | None = None,
                            batch_bytes: int = 64 << 20, plan: list[LevelStep] | None = None,
                            out: list[NDArray[np.float32]] | None = None,
                            level_seconds: dict[int, list[float]] | None = None) -> list[NDArray[np.float32]]:
    """The composed chain of ``P`` checked cubes ``a`` ``(P, 6, N, N, C)`` (finite float32 or
    float64; the same result for a float32 array and its float64 copy) on ``ctx``.

    Returns ``[(P, 6, N_k, N_k, C)]`` float32 (level 0 = the input).  Probes are filtered in
    batches whose level-0 source (float32 RGBA) fits ``batch_bytes``.  ``plan`` overrides
    :func:`~envcap.prefilter.composition.composition_plan` (tests force passes with it).  ``out``:
    the arrays to fill and return instead of new ones (float32, those shapes; ``out[0]`` may be
    ``a`` itself, then it is not copied).  ``level_seconds``: when given, each level ``k``'s dispatches
    add ``[wall s, CPU s]`` (``time.process_time``: llvmpipe's threads too) under ``k``, the GL
    queue finished before and after each (``envcap bench bake``).  Called by :func:`envcap.prefilter.fast.prefilter_many`
    for ``quality="composed"``.
    """
    p_all, _, n, _, nch = a.shape
    steps = composition_plan(ladder) if plan is None else plan
    shapes = [(p_all, 6, s, s, nch) for s in ladder.sizes]
    if out is None:
        chain = [np.empty(sh, np.float32) for sh in shapes]
    else:
        chain = list(out)
        if [x.shape for x in chain] != shapes or any(x.dtype != np.float32 for x in chain):
            raise ValueError(f"out must be float32 arrays of shapes {shapes}")
    if chain[0] is not a:
        chain[0][:] = a
    if ladder.levels == 1:
        return chain
    gl = _ComposedGL(ctx)
    gl.seconds = level_seconds
    per = max(1, int(batch_bytes // (6 * n * n * 16)))
    ones = ctx.buffer(reserve=4)  # nu of level 0: never read (direct passes)
    try:
        bar = tqdm(total=p_all * (ladder.levels - 1), desc="prefilter", unit="level",
                   disable=None if progress is None else not progress)
        for b0 in range(0, p_all, per):
            batch = a[b0:b0 + per]
            hot = _HotTexels(batch)
            for c0 in range(0, nch, 4):
                _filter_block(gl, batch, hot, c0, ladder, steps, ones, chain, b0)
            bar.update(batch.shape[0] * (ladder.levels - 1))
        bar.close()
    finally:
        ones.release()
        gl.release()
    return chain
