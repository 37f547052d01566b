"""``planes_mip_oblique``: ``planes_mip`` with the oblique mip shift.

As ``planes_mip``, sampled at ``z(w')`` with ``w' = w (d_probe / d_shade)^2 cos(alpha) / cos(beta)``:
the area of the lobe's footprint on the hit plane matched from the probe, ``alpha`` and ``beta``
the angles at which the shading point and the probe see that plane (``|n . d|``, ``|n . r|``;
docs/runtime.md, "Oblique, anisotropic mip shift").  Closed form, no extra fetch: 1 probe + 1 sky
fetch, like ``planes_mip``.  Needs: nominal planes.  Parameters: none.  GLSL:
``envcap_sample_oblique`` (``shaders/runtime/envcap_runtime.glsl``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.runtime.chains import ProbeChains
from envcap.runtime.footprint import footprint
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.mip import scale_power
from envcap.runtime.street import RuntimeStreet


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray) -> NDArray[np.float64]:
    """The nearest probe sampled towards the three-plane hit point at the oblique, area-matched level."""
    i = street.nearest(x)
    fp = footprint(x, d, street.positions[i], street.lookup_planes[i], street.along)
    return chains.fetch(fp.r, street.layers[i], scale_power(w, fp.q_iso))


METHOD = ParallaxMethod("planes_mip_oblique", street_rgba,
                        "planes_mip with the oblique (area-matched) mip shift, closed form",
                        glsl="envcap_sample_oblique")
