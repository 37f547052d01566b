"""Cosine-lobe mip chains: the exact float64 reference (:mod:`envcap.prefilter.exact`), the GL
filter a bake uses (:mod:`envcap.prefilter.fast`) and its composed mode
(:mod:`envcap.prefilter.composed`, ``quality="composed"``)."""

from envcap.prefilter.exact import (check_cosine_power, check_finite_cube, convolve_exact, convolve_exact_dirs,
                                    omega_box_pyramid)
from envcap.prefilter.composition import composition_plan
from envcap.prefilter.fast import QUALITIES, QUALITY, Quality, prefilter_chain, prefilter_level, prefilter_many
from envcap.prefilter.footprint import footprint_rects

__all__ = [
    "QUALITIES", "QUALITY", "Quality", "check_cosine_power", "check_finite_cube", "composition_plan", "convolve_exact",
    "convolve_exact_dirs", "footprint_rects", "omega_box_pyramid", "prefilter_chain", "prefilter_level",
    "prefilter_many",
]
