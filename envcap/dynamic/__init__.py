"""Dynamic occluders of the seed paper (Sections IV-VI): a sphere seen from a shading point as a
cosine lobe (:mod:`sphere_lobe`), the product of that lobe with a BRDF lobe (Eq. 4-7,
:mod:`lobe_product`, GLSL twin ``shaders/runtime/envcap_dynamic.glsl``) and the float64 reference
it is measured against (:mod:`quadrature`).  Derivations: ``docs/dynamic.md``."""

from envcap.dynamic.lobe_product import (
           LOBE_EXPONENT,
           MAX_POWER,
           LobeProduct,
           lobe_product,
)
from envcap.dynamic.quadrature import cap_lobe_integral
from envcap.dynamic.sphere_lobe import cap_solid_angle, lobe_power_matched, sphere_lobe

__all__ = [
           "LOBE_EXPONENT",
           "MAX_POWER",
           "LobeProduct",
           "cap_lobe_integral",
           "cap_solid_angle",
           "lobe_power_matched",
           "lobe_product",
           "sphere_lobe",
]
