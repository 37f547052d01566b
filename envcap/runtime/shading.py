"""Eq. 3 shading of the runtime (twin of ``envcap_lafortune_lobe`` in
``shaders/runtime/envcap_lobes.glsl`` and ``envcap_shade_lafortune`` in ``envcap_runtime.glsl``):
image-based lighting of a Lafortune BRDF from cos^w-convolved environment lookups.

Eq. 3 (docs/runtime.md)::

    L_o(v) ~ rho_d E_1(N) + sum_i rho_s[i] |Cv_i|^w_i 2 pi / (1 + w_i) max(c_i . N, 0) E_wi(c_i)

with ``Cv_i = C_i * v`` (component-wise, local frame, z = normal), ``c_i = Cv_i / |Cv_i|`` and
``E_w`` the environment convolved with the normalized cos^w lobe.  That is envcap's form
(``form="envcap"``, the default): lobes of the BRDF itself, foreshortening at the lobe axis.  The
paper's form (``form="paper"``) leaves out ``max(c_i . N, 0)``: its lobes are fitted to BRDF x cos
(docs/runtime.md, "Two forms of Eq. 3").  References (quadrature, no approximation):
:mod:`envcap.runtime.lafortune`.
"""

from __future__ import annotations

from typing import Any, Callable, Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.runtime.glsl_math import dot3
from envcap.runtime.limits import MAX_LOG2_WEIGHT

EnvironmentFn = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]
"""``env(dirs (..., 3) world unit, w (...)) -> (..., 3)``: the cos^w-convolved environment."""

Eq3Form = Literal["envcap", "paper"]
"""Form of Eq. 3: ``"envcap"`` (BRDF lobes x max(c . N, 0)) or ``"paper"`` (lobes fitted to
BRDF x cos, no cosine factor).  GLSL: ``#define ENVCAP_EQ3_PAPER_FORM`` selects ``"paper"``."""


def _check_form(form: str) -> None:
    if form not in get_args(Eq3Form):
        raise ValueError(f"Eq. 3 form must be one of {get_args(Eq3Form)}, got {form!r}")


def lafortune_lobe(v: ArrayLike, C: ArrayLike, w: ArrayLike, dtype: Any = np.float64,
                   form: Eq3Form = "envcap") -> tuple[NDArray, NDArray]:
    """Axis ``c`` (``(..., 3)``, local frame, unit) and weight of one Lafortune lobe for Eq. 3.

    ``v``: view directions in the local shading frame (z = normal), unit, ``(..., 3)``;
    ``C``: lobe coefficients ``(Cx, Cy, Cz)``; ``w``: lobe power.  ``weight = |Cv|^w * 2 pi /
    (1 + w) * max(c_z, 0)`` with ``Cv = C * v``.  Fallbacks: |Cv| = 0 -> c = (0,0,1), weight 0;
    log2 |Cv|^w clamped to MAX_LOG2_WEIGHT; w < 0 as 0.  ``dtype=np.float32``: GLSL order.
    ``form="paper"``: ``weight = |Cv|^w * 2 pi / (1 + w)`` (no cosine; see :data:`Eq3Form`).
    """
    _check_form(form)
    v, C, w = (np.asarray(a, dtype=dtype) for a in (v, C, w))
    w = np.maximum(w, dtype(0))
    cv = C * v
    ln = np.sqrt(dot3(cv, cv))
    ok = ln > 0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        c = cv / np.where(ok, ln, 1)[..., None]
        e = np.minimum(w * np.log2(np.where(ok, ln, 1)), dtype(MAX_LOG2_WEIGHT))
        mag = np.where(e < -126, dtype(0), np.exp2(e))
        wt = mag * (dtype(2.0 * np.pi) / (dtype(1) + w))
        if form == "envcap":
            wt = wt * np.maximum(c[..., 2], dtype(0))
    c = np.where(ok[..., None], c, np.array([0, 0, 1], dtype=dtype))
    wt = np.where(ok, wt, dtype(0))
    return c.astype(dtype), wt.astype(dtype)


def shade_lafortune(env: EnvironmentFn, v_local: ArrayLike, frame: ArrayLike, rho_d: ArrayLike, C: ArrayLike,
                    w: ArrayLike, rho_s: ArrayLike, form: Eq3Form = "envcap") -> NDArray[np.float64]:
    """Eq. 3 for a Lafortune BRDF (twin of GLSL ``envcap_shade_lafortune``), float64.

    ``env`` returns the cos^w-convolved environment (e.g. a closure over
    :func:`envcap.runtime.sampling.sample_street`).  ``v_local``: ``(..., 3)`` unit view
    directions in the local frame; ``frame``: ``(..., 3, 3)`` rows T, B, N (world); ``rho_d``:
    ``(3,)``; ``C``: ``(K, 3)``; ``w``: ``(K,)``; ``rho_s``: ``(K, 3)``.  Returns ``(..., 3)``.
    ``form``: which Eq. 3 (:data:`Eq3Form`); the diffuse term ``rho_d E_1(N)`` is the same in both.
    """
    _check_form(form)
    v = np.asarray(v_local, dtype=np.float64)
    F = np.asarray(frame, dtype=np.float64)
    Nw = F[..., 2, :]
    L = np.asarray(rho_d, np.float64) * env(Nw, np.ones(v.shape[:-1]))
    for Ci, wi, rs in zip(np.asarray(C, np.float64), np.asarray(w, np.float64), np.asarray(rho_s, np.float64)):
        c, wt = lafortune_lobe(v, Ci, wi, form=form)
        cw = np.einsum("...i,...ij->...j", c, F)
        L = L + rs * wt[..., None] * env(cw, np.full(v.shape[:-1], wi))
    return L
