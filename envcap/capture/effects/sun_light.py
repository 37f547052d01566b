"""``sun_light``: direct light from the sun on surfaces (Lambert), no occlusion.

* Needs: the sky's sun (``sky.sun``); listed without one, the effect is not applied.
* Parameters: none.  Per-set pass: none (the uniforms come straight from the sun).
* Uniforms: ``sun_dir`` (unit, toward the sun), ``sun_E`` (RGB illuminance at normal incidence).
* Irradiance term: ``E += sun_E max(0, n . sun_dir) V``, with ``V = 1``, or the shadow-map
  visibility ``sun_visibility`` of :mod:`envcap.capture.effects.sun_shadows` when that effect is
  applied too (``SUN_SHADOWS`` defined).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from envcap.capture.effects.base import CaptureEffect, EffectInputs, EffectSetup

GLSL_DECLARATIONS = """\
uniform vec3 sun_dir;        // unit, toward the sun
uniform vec3 sun_E;          // sun illuminance at normal incidence (RGB)
"""

GLSL_IRRADIANCE = """\
float c = max(dot(n, sun_dir), 0.0);
float vis = 1.0;
#ifdef SUN_SHADOWS
if (c > 0.0) vis = sun_visibility(v_local, n, c);
#endif
E += sun_E * (c * vis);
"""


def _prepare(inputs: EffectInputs, params: Mapping[str, Any]) -> EffectSetup:
    sun = inputs.sky.sun
    l = np.asarray(sun.direction, dtype=np.float64)
    return EffectSetup(uniforms={"sun_dir": (l / np.linalg.norm(l)).astype(np.float32),
                                 "sun_E": np.asarray(sun.illuminance, dtype=np.float32).reshape(3)})


EFFECT = CaptureEffect(
    name="sun_light",
    summary="direct light from the sun on surfaces (Lambert), no occlusion",
    needs=frozenset({"sun"}),
    uniforms=("sun_dir", "sun_E"),
    prepare=_prepare,
    glsl_declarations=GLSL_DECLARATIONS,
    glsl_irradiance=GLSL_IRRADIANCE,
)
