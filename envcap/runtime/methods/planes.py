"""``planes``: the nearest probe with three-plane parallax, without the mip shift.

The ray from the shading point ``x`` along ``d`` is intersected with the probe's three nominal
planes (two facades, the ground; :func:`envcap.runtime.parallax.parallax`); the probe is sampled
towards the hit point at the unshifted level ``z(w)``.  Needs: nominal planes.  Parameters:
none.  GLSL: none (``planes_mip`` without its shift).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.runtime.chains import ProbeChains
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.parallax import parallax
from envcap.runtime.street import RuntimeStreet


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray) -> NDArray[np.float64]:
    """The nearest probe sampled towards the three-plane hit point, level ``z(w)``."""
    i = street.nearest(x)
    r, _ = parallax(x, d, street.positions[i], street.lookup_planes[i], street.along)
    return chains.fetch(r, street.layers[i], w)


METHOD = ParallaxMethod("planes", street_rgba, "nearest probe, three nominal planes, no mip shift")
