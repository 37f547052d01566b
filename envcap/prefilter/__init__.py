"""Cosine-lobe mip chains: the exact float64 reference (:mod:`envcap.prefilter.exact`) and the
fast GL filter a bake uses (:mod:`envcap.prefilter.fast`)."""

from envcap.prefilter.exact import (check_cosine_power, check_finite_cube, convolve_exact, convolve_exact_dirs,
                                    omega_box_pyramid)
from envcap.prefilter.fast import QUALITY, Quality, footprint_rects, prefilter_chain, prefilter_level, prefilter_many

__all__ = [
    "QUALITY", "Quality", "check_cosine_power", "check_finite_cube", "convolve_exact", "convolve_exact_dirs",
    "footprint_rects", "omega_box_pyramid", "prefilter_chain", "prefilter_level", "prefilter_many",
]
