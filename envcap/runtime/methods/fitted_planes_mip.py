"""``fitted_planes_mip``: ``planes_mip`` with each probe's planes fitted from its own depth.

The bake fits the two facades and the ground to each probe's distance channel (manifest
``fitted_planes``); a plane that was not fitted stays nominal.  Needs: the fitted plane set
(``StreetProbes.runtime_street(planes="fitted")``).  Parameters: none.  GLSL:
``envcap_sample_nearest`` with the fitted planes uploaded.
"""

from __future__ import annotations

from envcap.runtime.methods import planes_mip
from envcap.runtime.methods.registry import ParallaxMethod

METHOD = ParallaxMethod("fitted_planes_mip", planes_mip.street_rgba,
                        "planes_mip with each probe's planes fitted from its own depth", planes="fitted",
                        glsl="envcap_sample_nearest")
