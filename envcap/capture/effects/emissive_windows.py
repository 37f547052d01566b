"""``emissive_windows``: emission of lit windows (materials with non-zero emission).

* Needs: nothing.  Parameters, uniforms, per-set pass: none.
* Radiance term: ``L += emission`` (the mesh's per-vertex emitted radiance), on front faces.
"""

from __future__ import annotations

from envcap.capture.effects.base import CaptureEffect

EFFECT = CaptureEffect(
    name="emissive_windows",
    summary="emission of lit windows (materials with non-zero emission)",
    glsl_radiance="L += v_emission;\n",
)
