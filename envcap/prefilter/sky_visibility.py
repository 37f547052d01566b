"""Visibility-weighted sky basis: ``filter(alpha Y_lm)`` per rung of a rung ladder, so that the
composite after filtering holds for a sky that changes after the bake (``docs/lobes.md``,
"Composite after filtering", "A sky that changes").

The runtime filters the street (premultiplied RGB ``S``, alpha) and the sky ``K'`` separately;
the truth is ``S_w + K'_w - filter(alpha K')``.  Projected on the real spherical harmonics up to
order ``l <= order`` (``K' ~ sum_lm K'_lm Y_lm``, ``K'_lm`` RGB), the last term is

    filter(alpha K') ~ sum_lm K'_lm V_lm,      V_lm = filter(alpha Y_lm)   (one scalar per lm),

so storing ``V`` per texel of the wide rungs lets the runtime correct the composite for any sky
given by its ``(order + 1)^2`` RGB coefficients (:mod:`envcap.runtime.sky_visibility`).

Basis (:func:`sh_basis`): real, orthonormal over the sphere, z as the polar axis, in the order
``l = 0..order``, ``m = -l..l``; ``l <= 2`` is :func:`envcap.capture.sky_sh.sh9_basis` (same
constants, same order).  :func:`band_factors`: the Legendre coefficients ``lambda_l`` of the
normalized ``cos^w`` lobe (``filter(Y_lm) = lambda_l(w) Y_lm``), ``lambda_0 = 1``,
``lambda_1 = (w + 1) / (w + 2)``, ``lambda_l = lambda_{l-2} (w - l + 2) / (w + l + 1)``.

Filter: each rung's lobe, the exact normalized ``cos^w`` average of :mod:`envcap.prefilter.exact`,
by Funk-Hecke through the spherical harmonics of alpha (:mod:`envcap.prefilter.visibility_harmonics`,
``quality="harmonics"``; the GL chains before it stay as ``quality="default"`` etc.).

Frame: ``V`` is in the alpha cube's own axes: for a probe of an angled street, its street's frame
(:mod:`envcap.core.street_frame`, texel ``f`` = world direction ``R^T f``); the runtime turns
world lookups into it (:func:`envcap.runtime.sky_visibility.sky_visible` ``yaw_deg``).

Storage (:class:`SkyVisibility`): the levels ``j >= first_level >= 1`` of the rung ladder (the
levels whose rungs all have ``w <= max_power``: 32^2, 16^2, 8^2 faces for ``max_power = 130``),
``(P R, 6, N_j, N_j, n_sh)`` float32, layer ``p R + r`` = rung ``j R + r`` of probe ``p``.
Packed for a GL cube-map array (:meth:`SkyVisibility.packed_levels`): the ``R n_sh`` scalars of a
probe at a texel are channels ``q = r n_sh + c`` of ``ceil(R n_sh / 4)`` RGBA layers (layer
``p G + q // 4``, component ``q % 4``), mip ``j - first_level``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, cast, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.capture.sky_sh import SH_C
from envcap.core import cube as cube_geometry
from envcap.core.lobes import LobeLadder
from envcap.core.rungs import RungLadder, rung_ladder
from envcap.gpu.context import create_context
from envcap.prefilter.fast import QUALITIES, Quality, prefilter_level, prefilter_many
from envcap.prefilter.visibility_harmonics import CHUNK_BYTES, degree_plan, harmonic_visibility, probe_bytes

__all__ = [
    "DEFAULT_MAX_POWER",
    "VISIBILITY_QUALITIES",
    "VisibilityQuality",
    "PREFILTER_BATCH_BYTES",
    "MAX_ORDER",
    "SkyVisibility",
    "band_factors",
    "band_of_coefficient",
    "first_stored_level",
    "prefilter_sky_visibility",
    "project_sh",
    "sh_basis",
    "sh_count",
    "sky_visibility_chunk",
    "visibility_bake_bytes",
    "visibility_bytes_per_probe",
]

VisibilityQuality = Literal["harmonics", "fast", "default", "high", "composed"]
VISIBILITY_QUALITIES: tuple[str, ...] = get_args(VisibilityQuality)
"""``quality`` of :func:`prefilter_sky_visibility`: ``"harmonics"`` (Funk-Hecke, the default) or a
GL filter's (the filter before it)."""
MAX_ORDER = 4
"""Highest SH order ``l`` supported (25 coefficients; GLSL ``ENVCAP_SKY_VIS_MAX_SH``)."""
PREFILTER_BATCH_BYTES = 64 << 20
"""The default ``batch_bytes`` of :func:`envcap.prefilter.fast.prefilter_many`: its batches are the
chunks of probes of :func:`prefilter_sky_visibility`'s GL qualities (:func:`sky_visibility_chunk`)."""
DEFAULT_MAX_POWER = 130.0
"""Levels with a rung of ``w`` above this are not stored (the composite error there is < 4 %)."""

_C3 = (0.5900435899266435, 2.890611442640554, 0.4570457994644658, 0.3731763325901154, 1.445305721320277)
_C4 = (2.5033429417967046, 1.7701307697799304, 0.9461746957575601, 0.6690465435572892, 0.10578554691520431,
       0.47308734787878004, 0.6258357354491761)


def sh_count(order: int) -> int:
    """``(order + 1)^2``; ``ValueError`` unless ``0 <= order <= MAX_ORDER``."""
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 0 <= order <= MAX_ORDER:
        raise ValueError(f"SH order must be an integer in [0, {MAX_ORDER}], got {order!r}")
    return (int(order) + 1) ** 2


def sh_basis(d: ArrayLike, order: int = 2) -> NDArray[np.float64]:
    """Real SH ``Y_lm`` (``l <= order``) of unit directions ``d`` ``(..., 3)`` -> ``(..., (order+1)^2)`` float64."""
    n = sh_count(order)
    d = np.asarray(d, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    c0, c1, c2, c3, c4 = SH_C
    cols = [np.full_like(x, c0), c1 * y, c1 * z, c1 * x, c2 * x * y, c2 * y * z, c3 * (3 * z * z - 1), c2 * x * z,
            c4 * (x * x - y * y)]
    if order >= 3:
        a, b, e, f, g = _C3
        cols += [a * y * (3 * x * x - y * y), b * x * y * z, e * y * (5 * z * z - 1), f * z * (5 * z * z - 3),
                 e * x * (5 * z * z - 1), g * z * (x * x - y * y), a * x * (x * x - 3 * y * y)]
    if order >= 4:
        a, b, e, f, g, h, k = _C4
        z2 = z * z
        cols += [a * x * y * (x * x - y * y), b * y * z * (3 * x * x - y * y), e * x * y * (7 * z2 - 1),
                 f * y * z * (7 * z2 - 3), g * (35 * z2 * z2 - 30 * z2 + 3), f * x * z * (7 * z2 - 3),
                 h * (x * x - y * y) * (7 * z2 - 1), b * x * z * (x * x - 3 * y * y),
                 k * (x * x * (x * x - 3 * y * y) - y * y * (3 * x * x - y * y))]
    return np.stack(cols[:n], axis=-1)


def band_factors(w: ArrayLike, order: int = 2) -> NDArray[np.float64]:
    """``lambda_l(w)``, ``l = 0..order``, of the normalized ``cos^w`` lobe: ``(..., order + 1)``
    float64 (``w >= 0``; ``+inf`` gives 1)."""
    sh_count(order)
    w = np.asarray(w, dtype=np.float64)
    inf = np.isinf(w)
    wf = np.where(inf, 0.0, w)
    lam = [np.ones_like(wf), (wf + 1.0) / (wf + 2.0)]
    for l in range(2, order + 1):
        lam.append(lam[l - 2] * (wf - l + 2.0) / (wf + l + 1.0))
    return np.where(inf[..., None], 1.0, np.stack(lam[:order + 1], axis=-1))


def project_sh(cube: ArrayLike, order: int = 2) -> NDArray[np.float64]:
    """``((order + 1)^2, C)``: the projection of a cube ``(6, N, N, C)`` on :func:`sh_basis` over the
    whole sphere (texel centres weighted by their exact solid angles), float64.  ``ValueError``
    for a bad shape or NaN/Inf texels."""
    a = np.asarray(cube, dtype=np.float64)
    if a.ndim != 4 or a.shape[0] != 6 or a.shape[1] != a.shape[2] or a.shape[1] < 1:
        raise ValueError(f"cube must have shape (6, N, N, C), got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError("cube has NaN/Inf texels: no SH coefficients")
    n = a.shape[1]
    basis = sh_basis(cube_geometry.texel_directions(n), order)
    return np.einsum("fijk,fij,fijc->kc", basis, cube_geometry.texel_solid_angles(n), a)


def band_of_coefficient(order: int) -> NDArray[np.int64]:
    """The band ``l`` of each coefficient of :func:`sh_basis` (``(n_sh,)``)."""
    return np.concatenate([np.full(2 * l + 1, l) for l in range(int(order) + 1)]).astype(np.int64)


@dataclass(frozen=True)
class SkyVisibility:
    """``V_lm = filter(alpha Y_lm)`` of ``P`` probes on the levels ``j >= first_level`` of ``ladder``.

    ``levels[j - first_level]``: ``(P R, 6, N_j, N_j, (order + 1)^2)`` float32 (layer ``p R + r``:
    rung ``j R + r``).  Every texel finite (checked).
    """

    levels: Sequence[NDArray[np.float32]]
    ladder: RungLadder
    order: int
    first_level: int

    def __post_init__(self) -> None:
        n_sh = sh_count(self.order)
        lv = [np.asarray(a) for a in self.levels]
        object.__setattr__(self, "levels", lv)
        if not 0 <= self.first_level < self.ladder.levels or len(lv) != self.ladder.levels - self.first_level:
            raise ValueError(f"sky visibility needs levels {self.first_level}..{self.ladder.levels - 1}, got {len(lv)}")
        for k, a in enumerate(lv):
            s = self.ladder.sizes[self.first_level + k]
            if a.ndim != 5 or a.shape[1:] != (6, s, s, n_sh) or a.shape[0] != lv[0].shape[0] \
                    or a.shape[0] % self.ladder.per_level:
                raise ValueError(f"sky visibility level {self.first_level + k} must be (P*{self.ladder.per_level}, 6, "
                                 f"{s}, {s}, {n_sh}), got {a.shape}")
            if not np.isfinite(a).all():
                raise ValueError(f"sky visibility level {self.first_level + k} has NaN/Inf values")

    @property
    def sh_count(self) -> int:
        return sh_count(self.order)

    @property
    def first_rung(self) -> int:
        """Flat index of the first stored rung (rungs below it have no ``V``)."""
        return self.first_level * self.ladder.per_level

    @property
    def probes(self) -> int:
        return self.levels[0].shape[0] // self.ladder.per_level

    @property
    def layers_per_probe(self) -> int:
        """RGBA layers per probe of the packed texture: ``ceil(R n_sh / 4)``."""
        return -(-self.ladder.per_level * self.sh_count // 4)

    def bytes_per_probe(self, bytes_per_texel: int = 8) -> int:
        """Bytes one probe takes in the packed texture (RGBA16F: 8 B per texel)."""
        return visibility_bytes_per_probe(self.ladder, self.order, first_level=self.first_level,
                                          bytes_per_texel=bytes_per_texel)

    def packed_levels(self) -> list[NDArray[np.float32]]:
        """``[(P G, 6, N_j, N_j, 4)]`` float32, ``G`` = :attr:`layers_per_probe`: the cube-map array the
        GLSL ``envcap_sky_visible`` reads (channel ``q = r n_sh + c`` of probe ``p`` at layer
        ``p G + q // 4``, component ``q % 4``; unused components 0)."""
        r_per, n_sh, g = self.ladder.per_level, self.sh_count, self.layers_per_probe
        out = []
        for a in self.levels:
            p_all, s = a.shape[0] // r_per, a.shape[2]
            flat = np.moveaxis(a.reshape(p_all, r_per, 6, s, s, n_sh), 1, -2).reshape(p_all, 6, s, s, r_per * n_sh)
            flat = np.concatenate([flat, np.zeros(flat.shape[:-1] + (4 * g - r_per * n_sh,), np.float32)], -1)
            out.append(np.ascontiguousarray(np.moveaxis(flat.reshape(p_all, 6, s, s, g, 4), 4, 1)
                                            .reshape(p_all * g, 6, s, s, 4), dtype=np.float32))
        return out


def first_stored_level(ladder: RungLadder, max_power: float = DEFAULT_MAX_POWER) -> int:
    """The first level ``j >= 1`` whose rungs all have ``w <= max_power`` (the last level if none;
    0 for a one-level ladder).  Level 0 (the capture's resolution) is stored only then."""
    if not (max_power >= 0 and math.isfinite(max_power)):
        raise ValueError(f"max_power must be finite and >= 0, got {max_power!r}")
    for j in range(1, ladder.levels):
        if ladder.level_powers(j)[0] <= max_power:
            return j
    return ladder.levels - 1


def visibility_bytes_per_probe(ladder: RungLadder, order: int = 2, max_power: float = DEFAULT_MAX_POWER,
                               first_level: int | None = None, bytes_per_texel: int = 8) -> int:
    """Bytes per probe of the packed :class:`SkyVisibility` of ``ladder`` (levels from
    ``first_level``, by default :func:`first_stored_level`; RGBA16F: 8 B per texel)."""
    j0 = first_stored_level(ladder, max_power) if first_level is None else int(first_level)
    layers = -(-ladder.per_level * sh_count(order) // 4)
    return int(layers * sum(6 * s * s for s in ladder.sizes[j0:]) * bytes_per_texel)


def prefilter_sky_visibility(alpha: ArrayLike, ladder: RungLadder, order: int = 2,
                             max_power: float = DEFAULT_MAX_POWER, quality: VisibilityQuality = "harmonics",
                             ctx: Any = None, batch_bytes: int = PREFILTER_BATCH_BYTES) -> SkyVisibility:
    """:class:`SkyVisibility` of the alpha cubes ``(P, 6, N, N)`` (or one ``(6, N, N)``) of captures.

    ``V_lm`` of rung ``i`` is the normalized ``cos^w_i`` average of :mod:`envcap.prefilter.exact`
    (the rungs' lobes; rung 0, stored only for a one-level ladder, unfiltered).  ``ValueError``:
    NaN/Inf alpha, a shape that is not the ladder's, a bad order or quality.

    ``quality="harmonics"`` (the default, what the bake runs): every rung from the spherical
    harmonics of ``alpha`` (:func:`envcap.prefilter.visibility_harmonics.harmonic_visibility`,
    Funk-Hecke: within ~1e-5 of the exact reference, ``docs/lobes.md``); no GL context; a rung past
    its reach (``w`` above ~340: a ``max_power`` far above the default) raises ``ValueError``.
    Memory: ``alpha`` as float32 once, the harmonics of one block of texels (``(degree + 1)^2`` x
    2048 float32), the coefficients (float64, ``(degree + 1)^2`` per probe and ``Y_c``).

    The GL qualities (``"fast"``, ``"default"``, ``"high"``, ``"composed"``: the filter before
    ``"harmonics"``, kept for comparison): each rung is the GL filter of
    :func:`envcap.prefilter.rungs.prefilter_rungs` (one chain per layer ``r``; level-0 rungs one
    cube at a time) on ``(alpha, alpha, alpha, alpha Y_1, .., alpha Y_{n-1})`` (the coarse texels at
    their alpha-weighted centroids; ``V_00 = Y_00 filter(alpha)``), float64, in chunks of probes of
    one batch of :func:`envcap.prefilter.fast.prefilter_many` (``batch_bytes`` over 16 B per
    level-0 texel, :func:`sky_visibility_chunk`), bit-identical to one call.
    """
    src = np.asarray(alpha)
    if not np.issubdtype(src.dtype, np.floating):
        src = src.astype(np.float64)
    if src.ndim == 3:
        src = src[None]
    sh_count(order)
    if src.ndim != 4 or src.shape[1] != 6 or src.shape[2] != src.shape[3] or src.shape[0] < 1:
        raise ValueError(f"alpha must be (P, 6, N, N) or (6, N, N), got shape {np.shape(alpha)}")
    if not np.isfinite(src).all():
        raise ValueError(f"alpha has {int((~np.isfinite(src)).sum())} NaN/Inf texels")
    p_all, _, n, _ = src.shape
    if n != ladder.sizes[0]:
        raise ValueError(f"alpha has {n}-texel faces, the rung ladder starts at {ladder.sizes[0]}")
    j0 = first_stored_level(ladder, max_power)
    if quality == "harmonics":
        return _harmonic_visibility(src, ladder, int(order), j0)
    if quality not in QUALITIES:
        raise ValueError(f"quality must be one of {sorted(VISIBILITY_QUALITIES)}, got {quality!r}")
    gl_quality = cast(Quality, quality)
    basis = sh_basis(cube_geometry.texel_directions(n), order)         # (6, n, n, n_sh)
    r_per, big_j = ladder.per_level, ladder.levels
    out = [np.empty((p_all * r_per, 6, s, s, 3 + basis.shape[-1] - 1), np.float32) for s in ladder.sizes[j0:]]
    per = sky_visibility_chunk(n, batch_bytes)
    own = ctx is None
    if own:
        ctx = create_context()
    try:
        for c0 in range(0, p_all, per):
            a = src[c0:c0 + per].astype(np.float64)
            chans = np.concatenate([np.repeat(a[..., None], 3, -1), a[..., None] * basis[None, ..., 1:]], -1)
            rows = slice(c0 * r_per, (c0 + a.shape[0]) * r_per)
            for r in range(r_per):
                if big_j > 1:
                    powers = (ladder.powers[0],) + tuple(ladder.level_powers(j)[r] for j in range(1, big_j))
                    chain = prefilter_many(chans, LobeLadder(ladder.sizes, powers), quality=gl_quality, ctx=ctx,
                                           progress=False, batch_bytes=batch_bytes)
                    for j in range(max(j0, 1), big_j):
                        out[j - j0][rows][r::r_per] = chain[j]
                    del chain
                if j0 == 0:
                    level_q = gl_quality if gl_quality != "composed" else "default"
                    for p in range(a.shape[0]):
                        out[0][rows][p * r_per + r] = chans[p] if r == 0 else \
                            prefilter_level(chans[p], ladder.powers[r], n, quality=level_q, ctx=ctx)
            del a, chans
    finally:
        if own:
            ctx.release()
    vis = [np.concatenate([SH_C[0] * o[..., :1], o[..., 3:]], -1).astype(np.float32) for o in out]
    return SkyVisibility(vis, ladder, int(order), j0)


def _harmonic_visibility(src: NDArray[np.floating], ladder: RungLadder, order: int, j0: int) -> SkyVisibility:
    """The stored levels of :func:`prefilter_sky_visibility` by ``quality="harmonics"``: each rung
    written into its layers (``p R + r``) of its level; rung 0 (``j0 = 0``) is ``alpha Y`` itself."""
    p_all, _, n, _ = src.shape
    r_per, n_sh = ladder.per_level, sh_count(order)
    levels = [np.empty((p_all * r_per, 6, s, s, n_sh), np.float32) for s in ladder.sizes[j0:]]
    rungs = [i for i in range(j0 * r_per, ladder.rungs) if i > 0]
    views = [levels[i // r_per - j0][i % r_per::r_per] for i in rungs]
    try:
        harmonic_visibility(src, [ladder.powers[i] for i in rungs], [ladder.sizes[i // r_per] for i in rungs], order,
                            lambda u: sh_basis(u, order), out=views)
    except ValueError as e:
        raise ValueError(f"{e}: a stored rung past the harmonics' reach (lower max_power, or quality='default', "
                         "the GL filter)") from None
    if j0 == 0:
        basis = sh_basis(cube_geometry.texel_directions(n), order).astype(np.float32)
        levels[0][0::r_per] = np.asarray(src, np.float32)[..., None] * basis
    return SkyVisibility(levels, ladder, order, j0)


def sky_visibility_chunk(resolution: int, batch_bytes: int = PREFILTER_BATCH_BYTES) -> int:
    """Probes per chunk of :func:`prefilter_sky_visibility`'s GL qualities at ``resolution`` texels
    per face: one batch of :func:`envcap.prefilter.fast.prefilter_many` (its rule: ``batch_bytes``
    over 16 B per level-0 texel, at least 1).  ``"harmonics"`` chunks by
    :func:`envcap.prefilter.visibility_harmonics.probe_bytes`."""
    return max(1, int(batch_bytes // (6 * resolution * resolution * 16)))


def visibility_bake_bytes(probes: float, resolution: float, order: int = 1) -> float:
    """Peak bytes the ``sky_visibility`` writer adds to a bake of ``probes`` probes at ``resolution``
    texels per face (``quality="harmonics"``, the half-octave ladder: the most rungs), for the bake's
    estimate (:func:`envcap.probeset.bake_bounds.estimate_bake`): the larger of the filter's peak
    (the float32 moments; one chunk of probes, :func:`envcap.prefilter.visibility_harmonics.probe_bytes`
    each; the harmonics of one block of texels, float32, and the recurrence's float64 rows; the
    orbits' texel indices and directions, ~530 B per texel of a face; the finiteness check, 1 B per
    texel of the set) and the write's (the moments, their packed copy and the half floats: 2.75 x
    the float32 moments).  The stored levels and the block are the same for every ``N >= 74``."""
    n = int(min(resolution, 256))
    lad = rung_ladder(n, "half_octave")
    j0, r_per = first_stored_level(lad), lad.per_level
    big, _ = degree_plan([lad.powers[i] for i in range(max(j0 * r_per, 1), lad.rungs)])
    per = probe_bytes(n, big, sh_count(order), lad.sizes[j0])
    block = min(4096, 3 * ((n + 1) // 2) ** 2)
    face = float(resolution) ** 2
    fixed = 5.0 * (big + order + 1) ** 2 * block + 64.0 * (big + order + 1) * block + 530.0 * face
    moments = 2.0 * visibility_bytes_per_probe(lad, order, first_level=j0) * probes   # float32: 2 x RGBA16F
    working = per * min(probes, max(1, CHUNK_BYTES // per)) + fixed + 6.0 * face * probes
    return max(moments + working, 2.75 * moments)
