"""``planes_mip_footprint``: ``planes_mip`` at the level of the lobe's traced footprint.

Four sigma rays of the cos^w lobe (``envcap.runtime.footprint.sigma_footprint``) are traced through
the nearest probe's three planes and seen from the probe; the level is that of the lobe with the
same solid angle, ``w' = 1 / sqrt(var_major var_minor) - 3``.  Unlike the closed form
(``planes_mip_oblique``) it follows a lobe over a street corner (facade and ground) and onto the
sky.  Cost: 1 probe + 1 sky fetch, like ``planes_mip``, plus four ray-plane intersections
(arithmetic).  Needs: nominal planes.  Parameters: none.  GLSL: ``envcap_sample_footprint``
(``shaders/runtime/envcap_runtime.glsl``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.runtime.chains import ProbeChains
from envcap.runtime.footprint import sigma_footprint
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.street import RuntimeStreet


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray) -> NDArray[np.float64]:
    """The nearest probe sampled towards the three-plane hit point at the traced footprint's level."""
    i = street.nearest(x)
    fp = sigma_footprint(x, d, w, street.positions[i], street.lookup_planes[i], street.along)
    return chains.fetch(fp.r, street.layers[i], fp.power())


METHOD = ParallaxMethod("planes_mip_footprint", street_rgba,
                        "planes_mip at the level of the lobe's traced footprint (4 sigma rays)",
                        glsl="envcap_sample_footprint")
