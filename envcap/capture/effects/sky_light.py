"""``sky_light``: light from the sky dome on surfaces (diffuse irradiance of the sky).

* Needs: a sky (its ``radiance``, sun excluded); listed without one, the effect is not applied.
* Parameters: ``sh_resolution`` (default 64), the cube face size in texels on which the sky's
  radiance is projected.
* Per-set pass ``sky_sh``: :func:`envcap.capture.sky_sh.sky_irradiance_sh`, the 9 irradiance SH
  coefficients of the upper hemisphere (ground bounce ignored).
* Uniforms: ``sky_sh`` (9 x RGB, ``E_lm = A_l L_lm``).
* Irradiance term: ``E += max(0, sum_lm E_lm Y_lm(n))`` (SH9 ringing can dip below 0 facing
  away from the sky).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from envcap.capture.effects.base import CaptureEffect, EffectInputs, EffectParameter, EffectSetup, positive_int
from envcap.capture.sky_sh import sky_irradiance_sh

# Basis constants as envcap.capture.sky_sh.SH_C, coefficient order as sh9_basis.
GLSL_DECLARATIONS = """\
uniform vec3 sky_sh[9];      // irradiance SH coefficients E_lm = A_l * L_lm (basis of sh9_basis)
vec3 sky_irradiance(vec3 n) {
    float x = n.x, y = n.y, z = n.z;
    vec3 e = sky_sh[0] * 0.282094791773878
           + sky_sh[1] * (0.488602511902920 * y)
           + sky_sh[2] * (0.488602511902920 * z)
           + sky_sh[3] * (0.488602511902920 * x)
           + sky_sh[4] * (1.092548430592079 * x * y)
           + sky_sh[5] * (1.092548430592079 * y * z)
           + sky_sh[6] * (0.315391565252520 * (3.0 * z * z - 1.0))
           + sky_sh[7] * (1.092548430592079 * x * z)
           + sky_sh[8] * (0.546274215296040 * (x * x - y * y));
    return max(e, vec3(0.0));   // SH9 ringing can dip below 0 facing away from the sky
}
"""

GLSL_IRRADIANCE = "E += sky_irradiance(n);\n"


def _prepare(inputs: EffectInputs, params: Mapping[str, Any]) -> EffectSetup:
    sh = sky_irradiance_sh(inputs.sky, params["sh_resolution"])
    return EffectSetup(uniforms={"sky_sh": sh.astype(np.float32)})


EFFECT = CaptureEffect(
    name="sky_light",
    summary="light from the sky dome on surfaces (diffuse irradiance of the sky)",
    needs=frozenset({"sky"}),
    parameters={"sh_resolution": EffectParameter(
        64, "cube face size (texels) on which the sky radiance is projected to SH",
        positive_int("sky_light parameter 'sh_resolution'"))},
    uniforms=("sky_sh",),
    pass_name="sky_sh",
    prepare=_prepare,
    glsl_declarations=GLSL_DECLARATIONS,
    glsl_irradiance=GLSL_IRRADIANCE,
)
