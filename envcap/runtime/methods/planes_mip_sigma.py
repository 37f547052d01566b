"""``planes_mip_sigma``: four lookups where the lobe's four sigma rays land, seen from the probe.

The four sigma rays of ``planes_mip_footprint`` (``envcap.runtime.footprint.sigma_footprint``) are
traced through the nearest probe's three planes; each becomes a tap towards
``r + (sqrt(F) / SPREAD) (v_i - r)`` (normalized; ``v_i`` the ray's hit seen from the probe,
``F`` = 0.75), read at the power of the variance ``(1 - F) V_minor`` (``V_minor``: the traced
footprint's minor axis).  For a linear footprint the four taps together have the footprint's
variance on its long axis up to ``(1 - F) V_minor``; unlike one lobe or taps along an axis
(``planes_mip_aniso``) they follow a footprint that a plane switch splits in two (a lobe grazing
one facade and reaching the other, or the ground and a facade): each tap sits where its ray lands.
Measured in docs/evaluation.md ("Narrow streets").  Cost: 4 probe fetches + 1 sky fetch, four
ray-plane intersections.  Needs: nominal planes.  Parameters: none.  GLSL:
``envcap_sample_sigma`` (``shaders/runtime/envcap_runtime.glsl``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.runtime.chains import ProbeChains
from envcap.runtime.footprint import SPREAD, sigma_footprint
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.street import RuntimeStreet

TAP_SHARE = 0.75
"""``F``: the share of the footprint's variance carried by the taps' spread (the rest by each
tap's own lobe).  Measured best of 0.5, 0.75, 0.9 in the canyon (w = 64).  GLSL ``ENVCAP_TAP_SHARE``."""


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray) -> NDArray[np.float64]:
    """Mean of four lookups of the nearest probe towards the sigma rays' hits."""
    i = street.nearest(x)
    fp = sigma_footprint(x, d, w, street.positions[i], street.lookup_planes[i], street.along)
    v_tap = (1.0 - TAP_SHARE) * fp.var_minor
    with np.errstate(divide="ignore", invalid="ignore"):
        w_tap = np.maximum(np.reciprocal(v_tap) - 3.0, 0.0)
    beta = np.sqrt(TAP_SHARE) / SPREAD
    acc = np.zeros(d.shape[:-1] + (4,), dtype=np.float64)
    for k in range(4):
        u = fp.r + beta * (fp.rays[..., k, :] - fp.r)
        acc += chains.fetch(u / np.linalg.norm(u, axis=-1, keepdims=True), street.layers[i], w_tap)
    return acc / 4.0


METHOD = ParallaxMethod("planes_mip_sigma", street_rgba,
                        "4 lookups where the lobe's sigma rays land (split footprints)", glsl="envcap_sample_sigma")
