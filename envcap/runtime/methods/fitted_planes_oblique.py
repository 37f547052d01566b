"""``fitted_planes_oblique``: ``planes_mip_oblique`` with each probe's planes fitted from its own depth.

The oblique (area-matched) mip shift of ``planes_mip_oblique`` on the fitted plane set (the bake
fits the two facades and the ground to each probe's distance channel, manifest ``fitted_planes``;
a plane that was not fitted stays nominal).  It is ``depth_refine`` without the distance read:
no extra fetch, 1 probe + 1 sky as ``planes_mip_oblique``.  Needs: the fitted plane set
(``StreetProbes.runtime_street(planes="fitted")``).  Parameters: none.  GLSL:
``envcap_sample_oblique`` with the fitted planes uploaded.
"""

from __future__ import annotations

from envcap.runtime.methods import planes_mip_oblique
from envcap.runtime.methods.registry import ParallaxMethod

METHOD = ParallaxMethod("fitted_planes_oblique", planes_mip_oblique.street_rgba,
                        "planes_mip_oblique with each probe's planes fitted from its own depth", planes="fitted",
                        glsl="envcap_sample_oblique")
