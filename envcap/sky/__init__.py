"""Skies: the :class:`Sky` interface, the sky registry, the Preetham / lat-long / uniform models, the sun.

Modules: :mod:`~envcap.sky.base` (interface, model record), :mod:`~envcap.sky.registry` (``[sky]``
-> :class:`SkySpec` -> :class:`Sky`), :mod:`~envcap.sky.sun`, :mod:`~envcap.sky.preetham`,
:mod:`~envcap.sky.latlong`, :mod:`~envcap.sky.uniform`, :mod:`~envcap.sky.checks`.
"""

from envcap.sky.base import Sky, SkyModel
from envcap.sky.latlong import LatLongSky
from envcap.sky.preetham import (
    DEFAULT_GROUND_ALBEDO,
    TURBIDITY_RANGE,
    XYZ_TO_RGB,
    PreethamSky,
    preetham_perez_coefficients,
    preetham_sun,
    preetham_zenith,
)
from envcap.sky.registry import SKY_MODELS, SkySpec, parse_sky_spec, register_sky, sky_from_spec
from envcap.sky.sun import (
    SOLAR_ILLUMINANCE_EXTRATERRESTRIAL,
    SUN_ANGULAR_RADIUS,
    Sun,
    SunTable,
    direction_from_angles,
    splat_sun,
    sun_disk_solid_angle,
)
from envcap.sky.uniform import UniformSky

__all__ = [
    "DEFAULT_GROUND_ALBEDO",
    "SKY_MODELS",
    "SOLAR_ILLUMINANCE_EXTRATERRESTRIAL",
    "SUN_ANGULAR_RADIUS",
    "TURBIDITY_RANGE",
    "XYZ_TO_RGB",
    "LatLongSky",
    "PreethamSky",
    "Sky",
    "SkyModel",
    "SkySpec",
    "Sun",
    "SunTable",
    "UniformSky",
    "direction_from_angles",
    "parse_sky_spec",
    "preetham_perez_coefficients",
    "preetham_sun",
    "preetham_zenith",
    "register_sky",
    "sky_from_spec",
    "splat_sun",
    "sun_disk_solid_angle",
]
