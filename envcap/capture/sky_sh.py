"""Diffuse sky irradiance as 9 spherical-harmonic coefficients (Ramamoorthi & Hanrahan 2001).

The ``sky_light`` capture effect projects the sky's radiance onto the real SH basis up to
``l = 2`` once per probe set; its fragment shader evaluates ``E(n) = sum_lm E_lm Y_lm(n)`` with
the same basis constants (``shaders/capture/capture_frag.glsl`` through
:mod:`envcap.capture.effects.sky_light`).  Directions are unit vectors of the envcap world
frame (+Y up); radiance is linear RGB.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube

SH_C: tuple[float, ...] = (0.282094791773878, 0.488602511902920, 1.092548430592079, 0.315391565252520,
                           0.546274215296040)
"""Real SH basis constants, in the order used by :func:`sh9_basis` and the GLSL."""

SH_COSINE_LOBE: NDArray[np.float64] = np.array([math.pi] + [2.0 * math.pi / 3.0] * 3 + [math.pi / 4.0] * 5)
"""(9,) clamped-cosine convolution factors ``A_l`` per coefficient (``A_0 = pi``, ``A_1 = 2 pi / 3``,
``A_2 = pi / 4``)."""


class SkyRadiance(Protocol):
    """What the projection needs from a sky (:class:`envcap.sky.Sky` has it)."""

    def radiance(self, dirs: NDArray[np.floating]) -> NDArray[np.floating]:
        """Linear RGB radiance ``(..., 3)`` toward unit directions ``dirs`` ``(..., 3)``, sun excluded."""
        ...


def sh9_basis(d: NDArray[np.floating]) -> NDArray[np.float64]:
    """Real SH basis ``Y_lm`` (l <= 2) of unit directions ``d`` (..., 3) -> (..., 9), float64."""
    d = np.asarray(d, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    c0, c1, c2, c3, c4 = SH_C
    return np.stack(
        [np.full_like(x, c0), c1 * y, c1 * z, c1 * x, c2 * x * y, c2 * y * z, c3 * (3 * z * z - 1), c2 * x * z,
         c4 * (x * x - y * y)],
        axis=-1,
    )


def sky_irradiance_sh(sky: SkyRadiance, n: int = 64) -> NDArray[np.float64]:
    """Irradiance SH coefficients ``E_lm = A_l L_lm``, shape ``(9, 3)``, of the sky dome.

    ``L_lm`` is the projection of ``sky.radiance`` (sun excluded: the sun is its own effect) over
    the upper hemisphere (directions with y < 0 contribute 0: ground bounce is ignored), summed
    over the texel centers of an ``n``-texel cube weighted by their exact solid angles.
    ``E(normal) = sum_lm E_lm Y_lm(normal)`` (:func:`sh9_basis`) is the irradiance of a surface.
    Raises ``ValueError`` if the sky radiance has the wrong shape or is not finite.
    """
    dirs = cube.texel_directions(n)
    w = cube.texel_solid_angles(n)
    rad = np.asarray(sky.radiance(dirs), dtype=np.float64)
    if rad.shape != dirs.shape:
        raise ValueError(f"sky.radiance returned shape {rad.shape}, expected {dirs.shape}")
    if not np.all(np.isfinite(rad)):
        raise ValueError("sky radiance contains NaN or Inf")
    rad = np.where(dirs[..., 1:2] >= 0.0, rad, 0.0)
    basis = sh9_basis(dirs)  # (6, n, n, 9)
    lm = np.einsum("fijk,fij,fijc->kc", basis, w, rad)
    return lm * SH_COSINE_LOBE[:, None]
