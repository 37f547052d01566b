"""The composite after filtering under a sky that changes after the bake (numpy twin of
``envcap_sky_visible`` in ``shaders/runtime/envcap_sky_visibility.glsl``; ``docs/lobes.md``,
"Composite after filtering", "A sky that changes").

The runtime composites ``C_w = S_w + K'_w - O_w``: ``S_w`` the street's premultiplied RGB, ``K'_w``
the new sky's rung lookup, ``O_w ~ filter(alpha K')`` the visible sky.  Without the bake's
:class:`envcap.prefilter.sky_visibility.SkyVisibility` the runtime uses ``O_w = alpha_w K'_w``
(today's ``S_w + (1 - alpha_w) K'_w``; ``alpha_w`` the rungs' alpha, sky-weighted for the baked
sky ``K`` by default).  With it, at a stored rung ``i`` (power ``w_i``, ``a_i = V_00,i / Y_00 =
filter(alpha)``), for SH coefficients ``D_lm`` and a base term ``B_w``:

    O_i = alpha_w B_w + sum_lm D_lm V_lm,i + a_i (K'_w - B_w - sum_lm D_lm lambda_l(w_i) Y_lm(d)).

* ``"sh"`` (``B = 0``, ``D = K'_lm``, no last term): ``filter(alpha K') ~ sum K'_lm V_lm``; its
  error is ``filter(alpha R)``, ``R = K' - K'_SH`` the sky's projection residual, large at narrow
  lobes;
* ``"sh_residual"`` with ``B = 0``, ``D = K'_lm``: the SH part carries the covariance of alpha
  and the band-limited sky, the residual is composited the old way; its error is
  ``-Cov_w(alpha, R)``;
* ``"sh_residual"`` with the baked sky as base (:func:`sky_delta`: ``B_w = s K_w``, ``D = K'_lm
  - s K_lm``, ``s`` the RGB least-squares scale of the new sky on the baked one): the sky-weighted
  alpha carries the baked sky's covariance (exact for it and any scaling of it), the SH the
  difference; the error is ``-Cov_w(alpha, R_D)``, ``R_D`` the residual of ``K' - s K``;
* the local gradient term (``gradient_of``, any of the ``"sh_residual"`` forms, order >= 1):
  ``+ sum_k (m_i . t_k) d/dt_k (C'_w - F_i)(d) / lambda_1(w_i)``, ``m_i = filter(alpha u)`` (the
  ``l = 1`` part of ``V``), ``t_k`` two tangents of ``d`` (:func:`tangent_frame`), ``C' = K' - B``
  looked up at ``d +- h t_k`` (central differences, ``h = GRADIENT_STEP / sqrt(w + 2)``), ``F_i =
  sum_lm D_lm lambda_l(w_i) Y_lm``: the covariance of alpha with a sky that is linear across the
  lobe, with the sky's *local* gradient instead of its global ``l = 1`` one.  ``"local"`` (``V``
  of l <= 1, ``D = 0``): 4 scalars per texel, 4 more rung fetches of the sky.

The measured choice (``docs/lobes.md``): ``V`` of order 1, the baked sky as base, ``D = 0``, the
gradient of ``K' - s K`` ("delta_local1").  The ``"sh_residual"`` forms are exact for alpha all
0 or all 1 (up to the lookup of ``V``).  Rungs not stored (``i < first_rung``, ``w >
max_power``) use ``alpha_w K'_w``.  ``O_w`` blends the rungs ``floor(u)`` and ``floor(u) + 1`` of
the rung position ``u`` as :func:`envcap.runtime.rungs.rung_fetch` does.  Float64.

Angled streets: a probe's ``V`` is in its street's frame (``R``, :mod:`envcap.core.street_frame`),
the sky in the world's; ``sky_visible(..., yaw_deg)`` reads ``V`` along ``R d``, turns ``D`` into
the frame (:func:`frame_coefficients`: ``l = 1`` as the vector, ``R k``) and the gradient's
tangents by ``R`` for ``m`` and ``F``, the sky's lookups staying along the world's ``d``
(derivation: ``docs/lobes.md``, "A sky that changes").
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.capture.sky_sh import SH_C
from envcap.core import cube as cube_geometry
from envcap.core import cube_sampling
from envcap.core.color import luminance
from envcap.core.rungs import rung_ladder
from envcap.core.street_frame import plan_rotation
from envcap.prefilter.sky_visibility import (
    DEFAULT_MAX_POWER,
    SkyVisibility,
    band_factors,
    band_of_coefficient,
    prefilter_sky_visibility,
    project_sh,
    sh_basis,
    sh_count,
)
from envcap.probeset.probe_set import ProbeSet
from envcap.runtime.rungs import rung_position, rung_table

__all__ = [
    "GLSL_MAX_SH",
    "GRADIENT_STEP",
    "Correction",
    "check_sky_coefficients",
    "composite_changed_sky",
    "frame_coefficients",
    "glsl_coefficients",
    "sh_projection_error",
    "sky_delta",
    "sky_sh_coefficients",
    "sky_visibility_of",
    "sky_visible",
    "tangent_frame",
]

Correction = Literal["sh", "sh_residual"]
GLSL_MAX_SH = 25
"""Length of the GLSL coefficient array ``ksh`` (``ENVCAP_SKY_VIS_MAX_SH``)."""
GRADIENT_STEP = 0.5
"""Central-difference step of the gradient term: ``h = GRADIENT_STEP / sqrt(w + 2)`` rad (half the
lobe's RMS angle; the result moves < 0.1 % between 0.4 and 1)."""


def check_sky_coefficients(k: ArrayLike, order: int) -> NDArray[np.float64]:
    """``k`` as ``((order + 1)^2, 3)`` float64; ``ValueError`` for a wrong shape or NaN/Inf values."""
    n = sh_count(order)
    a = np.asarray(k, dtype=np.float64)
    if a.shape != (n, 3):
        raise ValueError(f"sky SH coefficients must have shape ({n}, 3) for order {order}, got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"sky SH coefficients have {int((~np.isfinite(a)).sum())} NaN/Inf values")
    return a


def sky_sh_coefficients(sky: ArrayLike, order: int = 2) -> NDArray[np.float64]:
    """``K'_lm`` ``((order + 1)^2, 3)``: projection of the RGB of a sky cube ``(6, N, N, C >= 3)``
    on :func:`envcap.prefilter.sky_visibility.sh_basis` (:func:`~envcap.prefilter.sky_visibility.project_sh`:
    the whole sphere, exact texel solid angles).  ``ValueError`` for a bad shape or NaN/Inf texels."""
    a = np.asarray(sky, dtype=np.float64)
    if a.ndim != 4 or a.shape[-1] < 3:
        raise ValueError(f"sky must be a (6, N, N, C >= 3) cube, got shape {a.shape}")
    return check_sky_coefficients(project_sh(a[..., :3], order), order)


def sh_projection_error(sky: ArrayLike, k: ArrayLike, order: int) -> float:
    """Relative RMS (solid-angle weighted, luminance) of ``sky - sum_lm k_lm Y_lm`` over the sphere
    (the absolute RMS of the fit where ``sky`` is 0 everywhere)."""
    a = np.asarray(sky, dtype=np.float64)[..., :3]
    n = a.shape[1]
    fit = sh_basis(cube_geometry.texel_directions(n), order) @ check_sky_coefficients(k, order)
    om = cube_geometry.texel_solid_angles(n)
    y, yf = luminance(a), luminance(fit)
    den = float(np.sum(om * y ** 2))
    return float(np.sqrt(np.sum(om * (y - yf) ** 2) / den)) if den > 0 else float(np.sqrt(np.sum(om * yf ** 2)))


def sky_delta(k_new: ArrayLike, k_baked: ArrayLike, order: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(s, D)``: the RGB scale ``s`` ``(3,)`` of the new sky on the baked one (least squares over
    their SH coefficients, 0 where the baked channel is 0) and ``D = k_new - s k_baked`` ``(n_sh, 3)``.
    The runtime passes ``D`` as the coefficients and ``s K_w`` as the base (module docstring)."""
    kn, kb = check_sky_coefficients(k_new, order), check_sky_coefficients(k_baked, order)
    den = np.sum(kb * kb, axis=0)
    sc = np.where(den > 0, np.sum(kn * kb, axis=0) / np.where(den > 0, den, 1.0), 0.0)
    return sc, kn - sc * kb


def frame_coefficients(k: ArrayLike, yaw_deg: float, order: int) -> NDArray[np.float64]:
    """The world sky's SH coefficients ``k`` ``((order + 1)^2, 3)`` in the frame of a street at
    ``yaw_deg`` (:func:`envcap.core.street_frame.plan_rotation` ``R``): ``k_f`` with ``sum k_f Y(f)
    = sum k Y(R^T f)`` for every frame direction ``f`` (each band turns within itself; ``l = 1``:
    the vector ``(k_11, k_1-1, k_10)`` (x, y, z) becomes ``R`` times it, ``docs/lobes.md``).  Exact
    up to rounding (a least-squares fit on 96 directions, well posed for ``l <= 4``); ``yaw_deg = 0``
    returns ``k`` unchanged.  ``ValueError``: bad ``k``, a non-finite yaw."""
    kk = check_sky_coefficients(k, order)
    rot = plan_rotation(yaw_deg)
    if yaw_deg == 0.0:
        return kk.copy()
    x = cube_geometry.texel_directions(4).reshape(-1, 3)
    return np.linalg.lstsq(sh_basis(x, order), sh_basis(x @ rot, order) @ kk, rcond=None)[0]


def tangent_frame(d: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(t1, t2)`` ``(M, 3)``: unit tangents of unit ``d`` ``(M, 3)``, ``t1 = normalize(d x h)`` with
    ``h = +Y`` where ``|d.y| < 0.9`` (else ``+X``), ``t2 = d x t1`` (GLSL ``envcap_sky_tangents``)."""
    d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    helper = np.where(np.abs(d[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t1 = np.cross(d, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(d, t1)


def sky_visible(vis: SkyVisibility, d: ArrayLike, probe: ArrayLike, w: ArrayLike, k: ArrayLike,
                alpha_w: ArrayLike, sky_w: ArrayLike, correction: Correction = "sh_residual",
                base_w: ArrayLike | None = None,
                gradient_of: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
                yaw_deg: float = 0.0) -> NDArray[np.float64]:
    """``O_w ~ filter(alpha K')`` ``(M, 3)`` (module docstring) along unit world ``d`` ``(M, 3)`` of
    probe index ``probe`` for lobe power ``w`` (``w < 0``/NaN as 0, as the rung lookup), SH
    coefficients ``k`` = ``D`` ``(n_sh, 3)`` of the world's sky, the runtime's alpha ``alpha_w``
    ``(M,)``, new sky ``K'_w`` ``sky_w`` ``(M, 3)`` and base ``B_w`` ``base_w`` ``(M, 3)`` (``None``:
    0), all looked up along the world's ``d``.  ``gradient_of`` (with ``"sh_residual"``, order >= 1):
    ``world dirs (M, 3) -> (M, 3)``, the lookup of ``K' - B`` at the same ``w`` and probe rows: adds
    the local gradient term (module docstring).  ``yaw_deg``: the frame of the probes' street
    (:mod:`envcap.core.street_frame`; ``vis`` holds its probes' moments in that frame): ``V`` is
    read along ``R d``, ``k`` turned into the frame (:func:`frame_coefficients`), the tangents and
    steps of the gradient turned by ``R`` (``docs/lobes.md``, "A sky that changes"); 0: the world,
    the same numbers as without it."""
    if correction not in ("sh", "sh_residual"):
        raise ValueError(f"correction must be 'sh' or 'sh_residual', got {correction!r}")
    kk = check_sky_coefficients(k, vis.order)
    if gradient_of is not None and vis.order < 1:
        raise ValueError("the gradient term needs the l = 1 visibility moments (order >= 1)")
    d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    rot = plan_rotation(yaw_deg) if yaw_deg != 0.0 else None        # checks a non-finite yaw too
    if rot is not None:
        kk = frame_coefficients(kk, yaw_deg, vis.order)

    def fr(x: NDArray[np.float64]) -> NDArray[np.float64]:          # world -> the probes' frame
        return x if rot is None else x @ rot.T

    fd = fr(d)
    m = d.shape[0]
    lad, r_per = vis.ladder, vis.ladder.per_level
    nr = lad.rungs
    a_w = np.broadcast_to(np.asarray(alpha_w, np.float64).reshape(-1), (m,))
    s_w = np.broadcast_to(np.asarray(sky_w, np.float64).reshape(-1, 3), (m, 3))
    base = np.broadcast_to(np.asarray(probe, np.float64).reshape(-1), (m,)) * r_per
    u = np.broadcast_to(rung_position(np.where(np.asarray(w, np.float64) > 0, w, 0.0), rung_table(lad.powers)), (m,))
    i0 = np.floor(u).astype(np.int64)
    i1 = np.minimum(i0 + 1, nr - 1)
    t = (u - i0)[:, None]
    ylm = sh_basis(fd, vis.order)
    bands = band_of_coefficient(vis.order)
    powers = np.asarray(lad.powers, np.float64)
    b_w = np.zeros((m, 3)) if base_w is None else np.broadcast_to(np.asarray(base_w, np.float64).reshape(-1, 3), (m, 3))
    plain = a_w[:, None] * s_w
    grad = None
    h = np.ones((m, 1))
    if gradient_of is not None and correction == "sh_residual":
        wf = np.broadcast_to(np.asarray(w, np.float64), (m,))
        h = (GRADIENT_STEP / np.sqrt(np.minimum(np.where(wf > 0, wf, 0.0), 1e6) + 2.0))[:, None]
        grad = []
        for tk in tangent_frame(d):
            dp, dm = d + h * tk, d - h * tk
            dp, dm = dp / np.linalg.norm(dp, axis=1, keepdims=True), dm / np.linalg.norm(dm, axis=1, keepdims=True)
            grad.append((fr(tk), fr(dp), fr(dm),
                         (np.asarray(gradient_of(dp), np.float64) - np.asarray(gradient_of(dm), np.float64))
                         / (2.0 * np.sin(h))))

    def rung_term(i: NDArray[np.int64]) -> NDArray[np.float64]:
        stored = i >= vis.first_rung
        lod = np.maximum(i // r_per - vis.first_level, 0).astype(np.float64)
        v = cube_sampling.sample_cube_array(vis.levels, fd, base + (i % r_per), lod)     # (M, n_sh), frame
        o = a_w[:, None] * b_w + v @ kk
        if correction == "sh_residual":
            lam = band_factors(powers[i], vis.order)[:, bands]                             # (M, n_sh)
            o = o + (v[:, :1] / SH_C[0]) * (s_w - b_w - (lam * ylm) @ kk)
        if grad is not None:
            mom = v[:, [3, 1, 2]] / SH_C[1]                                      # filter(alpha u), xyz, frame
            lam1 = band_factors(powers[i], 1)[:, 1:2]
            for tk, dp, dm, dc in grad:
                df = ((lam * sh_basis(dp, vis.order)) @ kk - (lam * sh_basis(dm, vis.order)) @ kk) / (2.0 * np.sin(h))
                o = o + np.sum(mom * tk, axis=1, keepdims=True) * (dc - df) / lam1
        return np.where(stored[:, None], o, plain)

    a = rung_term(i0)
    return np.where(t > 0, a + t * (rung_term(i1) - a), a)


def composite_changed_sky(street_w: ArrayLike, sky_w: ArrayLike, visible: ArrayLike) -> NDArray[np.float64]:
    """``S_w + K'_w - O_w`` ``(M, 3)``: the composite after filtering with the visible sky ``O_w``
    (:func:`sky_visible`); ``street_w`` ``(M, C >= 3)`` premultiplied."""
    return np.asarray(street_w, np.float64)[..., :3] + np.asarray(sky_w, np.float64) - np.asarray(visible, np.float64)


def sky_visibility_of(probe_set: ProbeSet, mode: str = "half_octave", order: int = 2,
                      max_power: float = DEFAULT_MAX_POWER, quality: Any = "harmonics", ctx: Any = None) -> SkyVisibility:
    """The :class:`SkyVisibility` of ``probe_set``'s captures (their level 0 alpha) on
    ``rung_ladder(N, mode)``, as :func:`envcap.runtime.rungs.rung_chains_of` builds the rungs."""
    cap = np.asarray(probe_set.levels[0])
    if cap.shape[-1] < 4:
        raise ValueError(f"probe set captures have {cap.shape[-1]} channels: sky visibility needs their alpha")
    return prefilter_sky_visibility(cap[..., 3], rung_ladder(probe_set.resolution, mode), order, max_power,
                                    quality, ctx)


def glsl_coefficients(k: ArrayLike, order: int, yaw_deg: float = 0.0) -> NDArray[np.float32]:
    """The world sky's coefficients ``k`` turned into the frame of a street at ``yaw_deg``
    (:func:`frame_coefficients`; 0: ``k`` itself) and padded to the GLSL uniform ``vec3
    ksh[ENVCAP_SKY_VIS_MAX_SH]`` ``(25, 3)`` float32: one set per street and sky change."""
    kk = frame_coefficients(k, yaw_deg, order)
    out = np.zeros((GLSL_MAX_SH, 3), np.float32)
    out[:kk.shape[0]] = kk
    return out
