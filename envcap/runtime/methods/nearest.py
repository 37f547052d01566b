"""``nearest``: the probe nearest along the street, sampled along the lookup direction itself.

No parallax and no mip shift: the chain at ``d``, level ``z(w)``, as if the probe stood at the
shading point (the baseline every other method is measured against).  Needs: nominal planes
(only for the probe positions); no distance channel.  Parameters: none.  GLSL: none (it is
``textureLod(probes, vec4(d, layer), z(w))``, the "plain" lookup of ``envcap bench runtime``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.runtime.chains import ProbeChains
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.street import RuntimeStreet


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray) -> NDArray[np.float64]:
    """The nearest probe's chain along ``d`` at level ``z(w)``."""
    return chains.fetch(d, street.layers[street.nearest(x)], w)


METHOD = ParallaxMethod("nearest", street_rgba, "nearest probe along the street, no parallax")
