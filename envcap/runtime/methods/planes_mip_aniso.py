"""``planes_mip_aniso``: the traced footprint (``planes_mip_footprint``) with its anisotropy:
``taps`` lookups spread along the footprint's long axis.

The footprint seen from the probe (``envcap.runtime.footprint.sigma_footprint``) has per-axis
variances ``V_major >= V_minor``.  Each tap is a lobe of variance
``V_tap = max(V_minor, V_major / (1 + (taps^2 - 1) / 3))`` (neighbouring taps at most two tap
RMS angles apart, so they overlap), at power ``1 / V_tap - 3``; the taps sit along the long axis at
``r + c_i sqrt(V_major - V_tap) major`` (normalized), ``c_i`` equally spaced with mean square 1
(``envcap.runtime.footprint.tap_offsets``), so the sum of the taps has the footprint's variance on
both axes.  Equal weights; the mean street RGBA is composited over the sky once.  Cost: ``taps``
probe fetches + 1 sky fetch.  Needs: nominal planes.  Parameters: ``taps`` = 2 (GLSL:
``#define ENVCAP_ANISO_TAPS``, default 2).  GLSL: ``envcap_sample_aniso``
(``shaders/runtime/envcap_runtime.glsl``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.runtime.chains import ProbeChains
from envcap.runtime.footprint import sigma_footprint, tap_offsets
from envcap.runtime.methods.registry import ParallaxMethod
from envcap.runtime.street import RuntimeStreet

PARAMETERS = {"taps": 2}
"""Taps along the footprint's long axis (see the module docstring)."""


def street_rgba(chains: ProbeChains, street: RuntimeStreet, x: NDArray, d: NDArray, w: NDArray,
                taps: int = 2) -> NDArray[np.float64]:
    """Mean of ``taps`` lookups of the nearest probe along the traced footprint's long axis."""
    i = street.nearest(x)
    fp = sigma_footprint(x, d, w, street.positions[i], street.lookup_planes[i], street.along)
    v_tap = np.maximum(fp.var_minor, fp.var_major / (1.0 + (taps * taps - 1.0) / 3.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        w_tap = np.maximum(np.reciprocal(v_tap) - 3.0, 0.0)
    spread = np.sqrt(np.maximum(fp.var_major - v_tap, 0.0))
    acc = np.zeros(d.shape[:-1] + (4,), dtype=np.float64)
    for c in tap_offsets(taps):
        u = fp.r + (c * spread)[..., None] * fp.major
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        acc += chains.fetch(u, street.layers[i], w_tap)
    return acc / taps


METHOD = ParallaxMethod("planes_mip_aniso", street_rgba,
                        "traced footprint, 2 taps along its long axis (anisotropic)", parameters=PARAMETERS,
                        glsl="envcap_sample_aniso")
