"""envcap: street-level HDR environment probes for city scenes.

Capture probes along streets (along a world axis, or at any angle in plan in the street's own
frame: :mod:`envcap.core.street_frame`), filter them into cosine-lobe mip chains, and sample them
at runtime with three-plane parallax (Galvao, Laycock, Day: "Illuminating Crowds Via Integral
Approximation of Cosine Lobes").  Conventions: see :mod:`envcap.core.cube` and ``docs/conventions.md``.
"""

__version__ = "0.1.0"
