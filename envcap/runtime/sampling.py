"""The full runtime lookup, numpy twin of ``shaders/runtime/envcap_runtime.glsl``: the street
radiance a parallax method fetches from the probes, composited over the sky.

Float64; texture lookups through :mod:`envcap.core.cube_sampling` (the GL sampler's twin).
Vectors ``(..., 3)``; shading points in world meters, directions unit.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube_sampling
from envcap.runtime import methods
from envcap.runtime.chains import ProbeChains, SkyChain
from envcap.runtime.methods import ParallaxMethod
from envcap.runtime.mip import level_of_power
from envcap.runtime.rungs import rung_fetch
from envcap.runtime.street import RuntimeStreet


def composite(street: ArrayLike, sky: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """``street.rgb + (1 - clamp(street.a, 0, 1)) * sky`` (premultiplied street ``(..., 4)``; twin of
    GLSL ``envcap_composite``)."""
    st = np.asarray(street, dtype=dtype)
    sk = np.asarray(sky, dtype=dtype)
    return st[..., :3] + (dtype(1) - np.clip(st[..., 3:4], 0, 1)) * sk[..., :3]


def sample_sky(sky: SkyChain | Sequence[NDArray], d: ArrayLike, w: ArrayLike, xk: ArrayLike) -> NDArray[np.float64]:
    """The sky ``(..., C)`` along unit ``d`` at the unshifted level ``z(w)`` (the sky is at infinity:
    no parallax, no mip shift).  ``sky``: a :class:`SkyChain` or its levels ``[k]``:
    ``(6, M_k, M_k, C)`` on the ladder ``xk`` (checked finite: build the chain once to check once).
    A rung-ladder sky (``SkyChain.ladder``): two rungs blended on the rung table ``xk``."""
    chain = SkyChain.of(sky)
    if chain.ladder is not None:
        return rung_fetch(chain.levels, d, 0.0, w, xk, chain.ladder.per_level)
    return cube_sampling.sample_cube(chain.levels, d, level_of_power(w, xk))


def sample_street(chains: ProbeChains, sky_levels: SkyChain | Sequence[NDArray], street: RuntimeStreet, x: ArrayLike,
                  d: ArrayLike, w: ArrayLike, method: str | ParallaxMethod = "planes_mip") -> NDArray[np.float64]:
    """cos^w-convolved radiance ``(..., 3)`` seen from shading points ``x`` along unit ``d`` with lobe
    powers ``w`` (broadcast): the street RGBA of ``method`` (a registered name, see
    :mod:`envcap.runtime.methods`) composited over the sky ``sky_levels`` (a :class:`SkyChain`
    or its levels, checked finite before any lookup).

    Twin of GLSL ``envcap_sample_nearest`` for ``planes_mip`` and ``envcap_sample_blended`` for
    ``blend`` (each method names its GLSL function, if it has one).  ``street`` must carry the
    plane set the method needs (``ParallaxMethod.planes``).
    """
    m = methods.get(method)
    sky = SkyChain.of(sky_levels)
    x = np.asarray(x, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    shape = np.broadcast_shapes(x.shape, d.shape)
    d = np.broadcast_to(d, shape)
    w = np.broadcast_to(np.asarray(w, dtype=np.float64), shape[:-1])
    return composite(m(chains, street, x, d, w), sample_sky(sky, d, w, chains.xk))
