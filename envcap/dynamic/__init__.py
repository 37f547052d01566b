"""Dynamic occluders of the seed paper (Sections IV-VI): a sphere seen from a shading point as a
cosine lobe (:mod:`sphere_lobe`), the product of that lobe with a BRDF lobe (Eq. 4-7,
:mod:`lobe_product`, GLSL twin ``shaders/runtime/envcap_dynamic.glsl``) and the float64 reference
it is measured against (:mod:`quadrature`); envcap's better form of Eq. 7 (:mod:`cap_lobe`), many
spheres (:mod:`spheres`, the union of their caps on the lobe's rings :mod:`union`, GLSL
``envcap_dynamic_spheres.glsl``) and the blocked / bounced light of
a material (:mod:`terms`).  Derivations: ``docs/dynamic.md``."""

from envcap.dynamic.lobe_product import (
           LOBE_EXPONENT,
           MAX_POWER,
           LobeProduct,
           lobe_product,
)
from envcap.dynamic.cap_lobe import OcclusionForm, cap_lobe_product, occlusion
from envcap.dynamic.quadrature import cap_lobe_integral, union_lobe_fraction
from envcap.dynamic.spheres import SPHERE_CAP, CombineRule, Selection, SphereBuffer, combine, select_spheres
from envcap.dynamic.union import ring_union
from envcap.dynamic.terms import BounceRule, DynamicTerms, dynamic_terms, shade_with_spheres
from envcap.dynamic.sphere_lobe import cap_solid_angle, lobe_power_matched, sphere_lobe

__all__ = [
           "LOBE_EXPONENT",
           "MAX_POWER",
           "LobeProduct",
           "OcclusionForm",
           "SPHERE_CAP",
           "BounceRule",
           "CombineRule",
           "DynamicTerms",
           "Selection",
           "SphereBuffer",
           "cap_lobe_integral",
           "cap_lobe_product",
           "combine",
           "dynamic_terms",
           "occlusion",
           "select_spheres",
           "shade_with_spheres",
           "union_lobe_fraction",
           "ring_union",
           "cap_solid_angle",
           "lobe_power_matched",
           "lobe_product",
           "sphere_lobe",
]
