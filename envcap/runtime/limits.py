"""Limits and tolerances shared by the runtime GLSL and its numpy twin.

Each constant has a GLSL twin of the same value (``ENVCAP_<NAME>`` in ``shaders/runtime/``: a
``const float`` or an overridable ``#define``); ``tests/runtime/test_limits.py`` compiles the
GLSL and checks that both agree.  Units: meters for distances.
"""

from __future__ import annotations

FAR = 1.0e6
"""Hits farther than this (m) count as no hit (plane at infinity).  GLSL ``ENVCAP_FAR``."""
MIN_DIST = 1.0e-4
"""Distances (m) below this are clamped (zero-length probe vector, point on a plane).  GLSL ``ENVCAP_MIN_DIST``."""
MAX_RATIO = 256.0
"""Bound of the distance ratio d_probe / d_shade (at most 8 doublings of the lobe angle).  GLSL ``ENVCAP_MAX_RATIO``."""
MAX_LOG2_WEIGHT = 64.0
"""Upper bound of log2 |Cv|^w for Lafortune lobe weights.  GLSL ``ENVCAP_MAX_LOG2_WEIGHT``."""
MAX_LEVELS = 16
"""Most mip levels of a lobe table (length of the ``xk`` uniform array).  GLSL ``#define ENVCAP_MAX_LEVELS``."""
MAX_PROBES = 64
"""Most probes of one runtime street (length of its uniform arrays).  GLSL ``#define ENVCAP_MAX_PROBES``."""
MAX_LOBES = 3
"""Most specular lobes of a Lafortune material in ``envcap_shade_lafortune``.  GLSL ``#define ENVCAP_MAX_LOBES``."""
