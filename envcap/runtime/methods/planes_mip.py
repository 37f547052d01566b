"""``planes_mip``: the nearest probe with three-plane parallax and the mip shift (the paper).

As ``planes``, sampled at the shifted level ``z(w')``, ``w' = w (d_probe / d_shade)^2``: the lobe
seen from the shading point covers the patch of the hit plane that a lobe of power ``w'`` covers
seen from the probe (docs/runtime.md).  Needs: nominal planes.  Parameters: none.  GLSL:
``envcap_sample_nearest`` (``shaders/runtime/envcap_runtime.glsl``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.runtime.chains import ProbeChains
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.mip import shift_power
from envcap.runtime.parallax import parallax
from envcap.runtime.street import RuntimeStreet


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray) -> NDArray[np.float64]:
    """The nearest probe sampled towards the three-plane hit point at the shifted level (the street
    part of GLSL ``envcap_sample_probe``)."""
    i = street.nearest(x)
    r, ratio = parallax(x, d, street.positions[i], street.lookup_planes[i], street.along)
    return chains.fetch(r, street.layers[i], shift_power(w, ratio))


METHOD = ParallaxMethod("planes_mip", street_rgba, "nearest probe, three nominal planes + mip shift (the paper)",
                        glsl="envcap_sample_nearest")
