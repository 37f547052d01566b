"""Lafortune BRDFs, Eq. 3 (image-based lighting with cosine-lobe mip chains), and float64
quadrature references for both (no sampling noise).

Lafortune et al. 1997: ``f(u, v) = rho_d / pi + sum_i rho_s[i] * max(C_i . (u * v), 0)^w_i`` for
light direction ``u`` and view direction ``v`` in the local shading frame (z = normal); here
``C_i . (u * v) = u . Cv_i`` with ``Cv_i = (Cx v_x, Cy v_y, Cz v_z)``.  Eq. 3 (docs/runtime.md)::

    L_o(v) ~ rho_d E_1(n) + sum_i rho_s[i] |Cv_i|^w_i 2 pi / (1 + w_i) max(c_i . n, 0) E_wi(c_i)

with ``c_i = Cv_i / |Cv_i|`` and ``E_w(c) = (w + 1) / (2 pi) int max(c . u, 0)^w L(u) du`` (the
environment convolved with the normalized cos^w lobe: the mip chain).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube
from envcap.runtime.shading import Eq3Form, shade_lafortune

RadianceFn = Callable[[NDArray[np.float64]], NDArray[np.float64]]
"""Radiance of the environment for unit directions ``(..., 3)`` -> ``(..., 3)`` (world frame)."""


@dataclass(frozen=True)
class Lafortune:
    """A Lafortune BRDF: ``rho_d`` (3,), lobes ``C`` (K, 3), powers ``w`` (K,), ``rho_s`` (K, 3)."""

    rho_d: tuple[float, float, float]
    C: tuple[tuple[float, float, float], ...]
    w: tuple[float, ...]
    rho_s: tuple[tuple[float, float, float], ...]

    def __post_init__(self) -> None:
        k = len(self.C)
        if len(self.w) != k or len(self.rho_s) != k:
            raise ValueError("Lafortune: C, w and rho_s need one entry per lobe")
        vals = np.concatenate([np.ravel(self.rho_d), np.ravel(self.C), np.ravel(self.w), np.ravel(self.rho_s)])
        if not np.all(np.isfinite(vals)) or min(self.w, default=0) < 0:
            raise ValueError("Lafortune: parameters must be finite and powers >= 0")

    def brdf(self, u: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
        """``f(u, v)`` ``(..., 3)`` (1/sr) for local unit directions ``u``, ``v`` ``(..., 3)``."""
        u = np.asarray(u, np.float64)
        v = np.asarray(v, np.float64)
        f = np.broadcast_to(np.asarray(self.rho_d) / np.pi, np.broadcast_shapes(u.shape, v.shape)).copy()
        for C, w, rs in zip(self.C, self.w, self.rho_s):
            dot = np.einsum("...i,...i->...", u, np.asarray(C) * v)
            f = f + np.asarray(rs) * (np.maximum(dot, 0.0) ** w)[..., None]
        return f


def quadrature(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Directions ``(6 n^2, 3)`` (texel centers of an ``n`` cube) and their exact solid angles."""
    return cube.texel_directions(n).reshape(-1, 3), cube.texel_solid_angles(n).reshape(-1)


def reflected_radiance_reference(radiance: RadianceFn, mat: Lafortune, v_local: ArrayLike, frame: ArrayLike,
                                 n: int = 128) -> NDArray[np.float64]:
    """``int_{u . N > 0} f(u, v) L(u) (u . N) du`` by cube quadrature (``n`` texels a face), float64.

    ``v_local`` ``(M, 3)``; ``frame`` ``(M, 3, 3)`` rows T, B, N (world).  Returns ``(M, 3)``.
    """
    dirs, dw = quadrature(n)
    L = radiance(dirs)
    v = np.asarray(v_local, np.float64)
    F = np.asarray(frame, np.float64)
    out = np.empty((v.shape[0], 3))
    for m in range(v.shape[0]):
        ul = dirs @ F[m].T            # local coordinates of every quadrature direction
        cos = ul[:, 2]
        up = cos > 0
        f = mat.brdf(ul[up], v[m])
        out[m] = ((f * L[up]) * (cos[up] * dw[up])[:, None]).sum(axis=0)
    return out


def convolved_reference(radiance: RadianceFn, c: ArrayLike, w: ArrayLike, n: int = 128) -> NDArray[np.float64]:
    """``E_w(c)`` by cube quadrature, float64: ``c`` ``(M, 3)`` unit, ``w`` ``(M,)`` -> ``(M, 3)``."""
    dirs, dw = quadrature(n)
    L = radiance(dirs)
    c = np.asarray(c, np.float64)
    w = np.broadcast_to(np.asarray(w, np.float64), c.shape[:1])
    out = np.empty((c.shape[0], 3))
    for m in range(c.shape[0]):
        k = np.maximum(dirs @ c[m], 0.0) ** w[m] * dw
        out[m] = (k[:, None] * L).sum(axis=0) * (w[m] + 1.0) / (2.0 * np.pi)
    return out


def eq3(env: Callable[[NDArray, NDArray], NDArray], mat: Lafortune, v_local: ArrayLike, frame: ArrayLike,
        form: Eq3Form = "envcap") -> NDArray[np.float64]:
    """Eq. 3 with ``env(dirs (M, 3), w (M,)) -> (M, 3)`` the cos^w-convolved environment, in ``form``."""
    return shade_lafortune(env, v_local, frame, mat.rho_d, mat.C, mat.w, mat.rho_s, form=form)
