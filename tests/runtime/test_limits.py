"""The limits shared by the runtime GLSL and its numpy twin (envcap.runtime.limits) have the same
values on both sides: read back from a compiled shader."""

import numpy as np

from envcap.gpu.glsl_harness import run_glsl
from envcap.runtime import limits

BODY = """
if (i == 0u) o[i] = vec4(ENVCAP_FAR, ENVCAP_MIN_DIST, ENVCAP_MAX_RATIO, ENVCAP_MAX_LOG2_WEIGHT);
else o[i] = vec4(float(ENVCAP_MAX_LEVELS), float(ENVCAP_MAX_PROBES), float(ENVCAP_MAX_LOBES), 0.0);
"""


def test_glsl_constants_equal_python_limits(gl_ctx):
    out = run_glsl(gl_ctx, BODY, {"a": np.zeros(2)}, {"o": 4})["o"]
    want_f = np.array([limits.FAR, limits.MIN_DIST, limits.MAX_RATIO, limits.MAX_LOG2_WEIGHT], np.float32)
    np.testing.assert_array_equal(out[0], want_f)
    np.testing.assert_array_equal(out[1, :3], [limits.MAX_LEVELS, limits.MAX_PROBES, limits.MAX_LOBES])
