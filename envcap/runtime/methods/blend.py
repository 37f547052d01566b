"""``blend``: the two probes bracketing the shading point along the street, each with three-plane
parallax and the mip shift, blended with weights linear in the along-street coordinate.

Continuous along the street (no popping where the nearest probe changes); outside the probe
range the end probe alone.  Needs: nominal planes.  Parameters: none.  GLSL:
``envcap_sample_blended`` (``shaders/runtime/envcap_runtime.glsl``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.runtime.chains import ProbeChains
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.mip import shift_power
from envcap.runtime.parallax import parallax, probe_pair
from envcap.runtime.street import RuntimeStreet


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray) -> NDArray[np.float64]:
    """``(1 - t)`` probe ``i0`` + ``t`` probe ``i1``, each sampled like ``planes_mip``."""
    i0, i1, t = probe_pair(x[..., street.along], street.along_coords)
    acc = np.zeros(d.shape[:-1] + (4,), dtype=np.float64)
    for idx, wt in ((i0, 1.0 - t), (i1, t)):
        r, ratio = parallax(x, d, street.positions[idx], street.lookup_planes[idx], street.along)
        acc += wt[..., None] * chains.fetch(r, street.layers[idx], shift_power(w, ratio))
    return acc


METHOD = ParallaxMethod("blend", street_rgba, "two bracketing probes, each planes_mip, blended along the street",
                        glsl="envcap_sample_blended")
