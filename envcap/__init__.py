"""envcap: street-level HDR environment probes for city scenes.

Capture probes along axis-aligned streets, filter them into cosine-lobe mip chains, and sample
them at runtime with three-plane parallax (Galvao, Laycock, Day: "Illuminating Crowds Via
Integral Approximation of Cosine Lobes").  Conventions: see :mod:`envcap.core.cube`.
"""

__version__ = "0.1.0"
