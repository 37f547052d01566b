"""The Preetham, Shirley & Smits (1999) analytic clear sky with its sun (``[sky] type = "preetham"``).

Scene parameters (``[sky]`` keys; errors name the key):

* ``turbidity`` (required): atmospheric turbidity ``T`` in [2, 10] (the paper's fitted range).
* ``sun_elevation_deg`` (required): sun elevation in [0, 90] degrees.
* ``sun_azimuth_deg`` (default 0): azimuth in degrees from +Z towards +X, in [-360, 360].
* ``scale`` (default 1): factor on sky and sun, in [0, 10^6] (:data:`envcap.sky.checks.SCALE_LIMIT`).
* ``ground_albedo`` (default 0.2): diffuse reflectance in [0, 1] of the ground below the horizon.

Radiance in cd/m^2-scaled linear Rec.709 RGB; derivation and checks in ``docs/sky.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.sky.base import Sky, SkyModel
from envcap.core.checks import finite_float, float_in_range, unit_directions
from envcap.sky.checks import check_azimuth, check_elevation, check_scale
from envcap.sky.sun import SOLAR_ILLUMINANCE_EXTRATERRESTRIAL, SUN_ANGULAR_RADIUS, Sun, direction_from_angles

DEFAULT_GROUND_ALBEDO: float = 0.2
"""Diffuse reflectance of the ground below the horizon (Radiance ``gensky``'s default)."""

TURBIDITY_RANGE: tuple[float, float] = (2.0, 10.0)
"""Turbidities the Preetham fit supports (the paper's fitted range; see docs/sky.md)."""

XYZ_TO_RGB: NDArray[np.float64] = np.array(
    [[3.2404542, -1.5371385, -0.4985314],
     [-0.9692660, 1.8760108, 0.0415560],
     [0.0556434, -0.2040259, 1.0572252]])
"""CIE XYZ -> linear Rec.709 RGB (D65 white), rows R, G, B."""


# Effective wavelengths (micrometers) of the R, G, B channels for the sun's transmittance.
_RGB_WAVELENGTHS_UM = np.array([0.610, 0.550, 0.465])

# Preetham, Shirley, Smits 1999, appendix A.2: Perez coefficients (rows A..E) as (T, 1) pairs.
_PEREZ_Y = np.array([[0.1787, -1.4630], [-0.3554, 0.4275], [-0.0227, 5.3251], [0.1206, -2.5771], [-0.0670, 0.3703]])
_PEREZ_x = np.array([[-0.0193, -0.2592], [-0.0665, 0.0008], [-0.0004, 0.2125], [-0.0641, -0.8989], [-0.0033, 0.0452]])
_PEREZ_y = np.array([[-0.0167, -0.2608], [-0.0950, 0.0092], [-0.0079, 0.2102], [-0.0441, -1.6537], [-0.0109, 0.0529]])
# Zenith chromaticity: rows T^2, T, 1; columns theta_s^3, theta_s^2, theta_s, 1.
_ZENITH_x = np.array([[0.00166, -0.00375, 0.00209, 0.0], [-0.02903, 0.06377, -0.03202, 0.00394],
                      [0.11693, -0.21196, 0.06052, 0.25886]])
_ZENITH_y = np.array([[0.00275, -0.00610, 0.00317, 0.0], [-0.04214, 0.08970, -0.04153, 0.00516],
                      [0.15346, -0.26756, 0.06670, 0.26688]])


def check_turbidity(t: Any, name: str = "turbidity") -> float:
    """A turbidity inside :data:`TURBIDITY_RANGE`."""
    return float_in_range(t, name, *TURBIDITY_RANGE)


def check_ground_albedo(value: Any, name: str = "ground albedo") -> float:
    """A ground albedo in [0, 1]."""
    return float_in_range(value, name, 0.0, 1.0)


def preetham_perez_coefficients(turbidity: float) -> NDArray[np.float64]:
    """Perez coefficients ``A..E`` for ``Y``, ``x``, ``y``: shape ``(3, 5)`` (paper, appendix A.2)."""
    t = check_turbidity(turbidity)
    return np.stack([m[:, 0] * t + m[:, 1] for m in (_PEREZ_Y, _PEREZ_x, _PEREZ_y)])


def preetham_zenith(turbidity: float, sun_zenith: float) -> tuple[float, float, float]:
    """Zenith luminance (cd/m^2) and chromaticity ``(Y_z, x_z, y_z)``; ``sun_zenith`` in radians.

    ``Y_z = 1000 [(4.0453 T - 4.9710) tan(chi) - 0.2155 T + 2.4192]`` with
    ``chi = (4/9 - T/120)(pi - 2 theta_s)`` (the paper gives kcd/m^2); ``x_z``, ``y_z`` are the
    paper's cubic polynomials in ``theta_s`` with quadratic dependence on ``T``.
    """
    t = check_turbidity(turbidity)
    ts = finite_float(sun_zenith, "sun zenith")
    if not 0.0 <= ts <= math.pi / 2 + 1e-12:
        raise ValueError(f"sun zenith must be in [0, pi/2] radians, got {ts}")
    chi = (4.0 / 9.0 - t / 120.0) * (math.pi - 2.0 * ts)
    yz = 1000.0 * ((4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192)
    tv = np.array([t * t, t, 1.0])
    th = np.array([ts ** 3, ts ** 2, ts, 1.0])
    return yz, float(tv @ _ZENITH_x @ th), float(tv @ _ZENITH_y @ th)


def _perez(coef: NDArray[np.float64], cos_theta: NDArray, gamma: NDArray, cos_gamma: NDArray) -> NDArray:
    a, b, c, d, e = coef
    # cos_theta is clamped away from 0: exp(B / cos) -> 0 at the horizon (B < 0 for T >= 2).
    return (1.0 + a * np.exp(b / np.maximum(cos_theta, 1e-6))) * (1.0 + c * np.exp(d * gamma) + e * cos_gamma ** 2)


def preetham_sun(turbidity: float, elevation_deg: float, azimuth_deg: float,
                 scale: float = 1.0) -> Sun:
    """The sun for a Preetham sky: extraterrestrial illuminance times per-channel transmittance.

    ``E_rgb = 128 klx * exp(-m (0.008735 lambda^-4.08 + beta lambda^-1.3))`` with the Rayleigh and
    Angstrom aerosol optical depths of Preetham et al. (appendix A.4/A.5, ``beta = 0.04608 T -
    0.04586``, ``alpha = 1.3``), evaluated at effective channel wavelengths 610/550/465 nm, and the
    relative air mass ``m = 1 / (cos z + 0.15 (93.885 - z_deg)^-1.253)`` (Kasten 1966, as in the
    paper).  Ozone, water vapour and mixed-gas absorption are neglected.  The disk radiance is
    ``E / (2 pi (1 - cos 0.2665 deg))``.
    """
    t = check_turbidity(turbidity)
    e = check_elevation(elevation_deg)
    z_deg = 90.0 - e
    m = 1.0 / (math.cos(math.radians(z_deg)) + 0.15 * (93.885 - z_deg) ** -1.253)
    beta = 0.04608 * t - 0.04586
    lam = _RGB_WAVELENGTHS_UM
    tau = np.exp(-m * (0.008735 * lam ** -4.08 + beta * lam ** -1.3))
    illum = SOLAR_ILLUMINANCE_EXTRATERRESTRIAL * tau * scale
    return Sun.from_illuminance(direction_from_angles(e, azimuth_deg), illum, SUN_ANGULAR_RADIUS)


def _into_gamut(rgb: NDArray[np.float64], lum: NDArray[np.float64]) -> NDArray[np.float64]:
    """Desaturate out-of-gamut (negative) Rec.709 colors towards grey of the same luminance.

    ``rgb' = Y + k (rgb - Y)`` with the largest ``k`` in [0, 1] that makes every channel >= 0;
    luminance is preserved exactly (the luminance weights sum to 1).  In-gamut colors are unchanged.
    """
    y = np.maximum(lum, 0.0)[..., None]
    lo = rgb.min(axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(lo < 0.0, y / np.maximum(y - lo, 1e-300), 1.0)
    k = np.clip(k, 0.0, 1.0)
    return np.maximum(y + k * (rgb - y), 0.0)


class PreethamSky(Sky):
    """Preetham, Shirley & Smits (1999) clear sky with its sun.

    ``turbidity`` in [2, 10]; sun elevation in [0, 90] deg; azimuth from +Z towards +X, degrees.
    ``scale`` multiplies sky and sun.  Below the horizon (``y < 0``) the radiance is the constant
    ground-bounce ``albedo * E_h / pi``, where ``E_h`` is the horizontal illuminance of the upper
    sky dome plus the sun (float64 quadrature at construction).
    """

    def __init__(self, turbidity: float, sun_elevation_deg: float, sun_azimuth_deg: float = 0.0,
                 scale: float = 1.0, ground_albedo: float = DEFAULT_GROUND_ALBEDO, supersample: int = 4) -> None:
        self.turbidity = check_turbidity(turbidity)
        self.sun_elevation_deg = check_elevation(sun_elevation_deg)
        self.sun_azimuth_deg = check_azimuth(sun_azimuth_deg, "sun azimuth")
        self.scale = check_scale(scale)
        self.ground_albedo = check_ground_albedo(ground_albedo)
        self.supersample = int(supersample)
        self.sun_direction = direction_from_angles(self.sun_elevation_deg, self.sun_azimuth_deg)
        self.sun = preetham_sun(self.turbidity, self.sun_elevation_deg, self.sun_azimuth_deg, self.scale)
        self.theta_s = math.radians(90.0 - self.sun_elevation_deg)
        self.zenith = preetham_zenith(self.turbidity, self.theta_s)
        self.coefficients = preetham_perez_coefficients(self.turbidity)
        cs = math.cos(self.theta_s)
        self._norm = np.array([float(_perez(c, np.float64(1.0), np.float64(self.theta_s), np.float64(cs)))
                               for c in self.coefficients])
        self.horizontal_sky_illuminance = self._horizontal_sky_illuminance()
        e_h = self.horizontal_sky_illuminance + self.sun.illuminance * max(0.0, float(self.sun.direction[1]))
        self.ground_radiance = self.ground_albedo * e_h / math.pi

    def _upper(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """Preetham radiance for unit directions (the y < 0 half is evaluated at the horizon)."""
        cos_t = np.clip(d[..., 1], 0.0, 1.0)
        cos_g = np.clip(d @ self.sun_direction, -1.0, 1.0)
        gamma = np.arccos(cos_g)
        yz, xz, ycz = self.zenith
        vals = [z * _perez(c, cos_t, gamma, cos_g) / nrm
                for z, c, nrm in zip((yz, xz, ycz), self.coefficients, self._norm)]
        lum, x, y = vals
        xyz = np.stack([x / y * lum, lum, (1.0 - x - y) / y * lum], axis=-1)
        return _into_gamut(xyz @ XYZ_TO_RGB.T, lum) * self.scale

    def _horizontal_sky_illuminance(self, n_theta: int = 192, n_phi: int = 384) -> NDArray[np.float64]:
        # Midpoint rule over the upper hemisphere: E = sum L cos(theta) sin(theta) dtheta dphi.
        th = (np.arange(n_theta) + 0.5) * (0.5 * math.pi / n_theta)
        ph = (np.arange(n_phi) + 0.5) * (2.0 * math.pi / n_phi)
        T, P = np.meshgrid(th, ph, indexing="ij")
        d = np.stack([np.sin(T) * np.sin(P), np.cos(T), np.sin(T) * np.cos(P)], axis=-1)
        w = np.cos(T) * np.sin(T) * (0.5 * math.pi / n_theta) * (2.0 * math.pi / n_phi)
        return np.einsum("ijc,ij->c", self._upper(d), w)

    def radiance(self, dirs: NDArray) -> NDArray[np.float64]:
        d = unit_directions(dirs)
        up = self._upper(d)
        return np.where(d[..., 1:2] >= 0.0, up, self.ground_radiance)

    def spec(self) -> dict[str, Any]:
        return {
            "type": "preetham",
            "turbidity": self.turbidity,
            "sun_elevation_deg": self.sun_elevation_deg,
            "sun_azimuth_deg": self.sun_azimuth_deg,
            "scale": self.scale,
            "ground_albedo": self.ground_albedo,
            "sun_light": self.sun_light(),
        }


@dataclass(frozen=True)
class PreethamParams:
    """The checked ``[sky]`` parameters of a Preetham sky (keys and units in the module docstring)."""

    turbidity: float
    sun_elevation_deg: float
    sun_azimuth_deg: float = 0.0
    scale: float = 1.0
    ground_albedo: float = DEFAULT_GROUND_ALBEDO

    @classmethod
    def parse(cls, table: dict[str, Any], base_dir: Path | None = None) -> "PreethamParams":
        """Check the values of a key-checked ``[sky]`` table (``base_dir`` is unused: no files)."""
        return cls(turbidity=check_turbidity(table["turbidity"], "sky.turbidity"),
                   sun_elevation_deg=check_elevation(table["sun_elevation_deg"], "sky.sun_elevation_deg"),
                   sun_azimuth_deg=check_azimuth(table.get("sun_azimuth_deg", 0.0), "sky.sun_azimuth_deg"),
                   scale=check_scale(table.get("scale", 1.0), "sky.scale"),
                   ground_albedo=check_ground_albedo(table.get("ground_albedo", DEFAULT_GROUND_ALBEDO),
                                                     "sky.ground_albedo"))

    def build(self) -> PreethamSky:
        return PreethamSky(self.turbidity, self.sun_elevation_deg, self.sun_azimuth_deg, self.scale,
                           self.ground_albedo)


PREETHAM = SkyModel(
    name="preetham",
    required=frozenset({"turbidity", "sun_elevation_deg"}),
    optional=frozenset({"sun_azimuth_deg", "scale", "ground_albedo"}),
    parse=PreethamParams.parse,
    build=PreethamParams.build,
)
"""The registry entry of the Preetham sky."""
