"""Parallax methods of the runtime, one file each, and their registry.

Every method file defines ``METHOD``, a :class:`ParallaxMethod` (name, the function that fetches
the street radiance, what it needs, its parameters), documented in its module docstring.  A new
method is one file here plus one entry in the ``BUILTIN`` line below (or a :func:`register` call
from outside the package); the evaluator (``envcap evaluate --methods``) and the runtime twin
(:func:`envcap.runtime.sampling.sample_street`) find it by name.
"""

from __future__ import annotations

from envcap.runtime.methods import (blend, depth_refine, depth_reproject, fitted_planes_mip, fitted_planes_oblique, nearest,
                                    planes, planes_mip, planes_mip_aniso, planes_mip_footprint, planes_mip_oblique,
                                    planes_mip_sigma)
from envcap.runtime.methods.registry import ParallaxMethod, StreetRGBA, get, register, registered, unregister

BUILTIN: tuple[ParallaxMethod, ...] = (nearest.METHOD, planes.METHOD, planes_mip.METHOD, blend.METHOD,
                                       fitted_planes_mip.METHOD, depth_reproject.METHOD, planes_mip_oblique.METHOD,
                                       planes_mip_footprint.METHOD, planes_mip_aniso.METHOD, planes_mip_sigma.METHOD,
                                       fitted_planes_oblique.METHOD, depth_refine.METHOD)
"""The built-in methods, simplest first (the order of reports)."""

for _method in BUILTIN:
    register(_method)

METHODS: tuple[str, ...] = tuple(m.name for m in BUILTIN)
"""Names of the built-in methods, simplest first (the evaluator's default)."""

__all__ = ["BUILTIN", "METHODS", "ParallaxMethod", "StreetRGBA", "get", "register", "registered", "unregister"]
