"""HDR skies for envcap: an analytic daylight sky (Preetham et al. 1999), lat-long files, and a
uniform test sky, each with an optional analytic sun.  Derivation and decisions: ``docs/sky.md``.

Units and conventions
---------------------
* Radiance is linear Rec.709 RGB scaled so that the luminance ``Y = 0.2126 R + 0.7152 G +
  0.0722 B`` is in cd/m^2 (for the Preetham sky; a lat-long file is taken in its own units times
  ``scale``).  Illuminance is then in lux (lm/m^2).
* World frame right-handed, +Y up.  A direction of elevation ``e`` and azimuth ``a`` is
  ``(cos e sin a, sin e, cos e cos a)``: azimuth is measured from +Z towards +X (it equals the
  lat-long longitude of :mod:`envcap.core.latlong`; azimuth 90 deg is +X).
* The sun is kept twice (lead's decision): as an analytic :class:`Sun` (direction, disk radiance,
  angular radius, illuminance at normal incidence) for manifests and direct lighting, and splatted
  into float32 sky cubes so that ``sum(texel radiance * texel solid angle)`` over the sun's
  contribution equals ``Sun.illuminance`` at any cube size (N = 1 included).  Nothing is clipped:
  values up to ~1e12 are finite in float32 (they are not in float16; half-float consumers must
  take the sun from the manifest instead).
* :meth:`Sky.radiance` is the dome *without* the sun disk, finite for every direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube as _cube
from envcap.core.latlong import cube_texel_average, latlong_to_cube, load_latlong, sample_latlong

__all__ = [
    "SUN_ANGULAR_RADIUS",
    "SOLAR_ILLUMINANCE_EXTRATERRESTRIAL",
    "DEFAULT_GROUND_ALBEDO",
    "TURBIDITY_RANGE",
    "XYZ_TO_RGB",
    "RGB_LUMINANCE",
    "Sun",
    "Sky",
    "PreethamSky",
    "LatLongSky",
    "UniformSky",
    "direction_from_angles",
    "preetham_zenith",
    "preetham_perez_coefficients",
    "preetham_sun",
    "sun_disk_solid_angle",
    "splat_sun",
    "sky_from_spec",
]

SUN_ANGULAR_RADIUS: float = math.radians(0.2665)
"""Angular radius of the solar disk, radians (0.2665 deg, mean Earth-Sun distance)."""

SOLAR_ILLUMINANCE_EXTRATERRESTRIAL: float = 128_000.0
"""Solar illuminance at normal incidence outside the atmosphere, lux (the daylighting literature's
value 127.5-133 klx; 128 klx used here)."""

DEFAULT_GROUND_ALBEDO: float = 0.2
"""Diffuse reflectance of the ground below the horizon (Radiance ``gensky``'s default)."""

TURBIDITY_RANGE: tuple[float, float] = (2.0, 10.0)
"""Turbidities the Preetham fit supports (the paper's fitted range; see docs/sky.md)."""

XYZ_TO_RGB: NDArray[np.float64] = np.array(
    [[3.2404542, -1.5371385, -0.4985314],
     [-0.9692660, 1.8760108, 0.0415560],
     [0.0556434, -0.2040259, 1.0572252]])
"""CIE XYZ -> linear Rec.709 RGB (D65 white), rows R, G, B."""

RGB_LUMINANCE: NDArray[np.float64] = np.array([0.2126729, 0.7151522, 0.0721750])
"""Luminance Y of linear Rec.709 RGB (the Y row of RGB -> XYZ)."""

# Effective wavelengths (micrometers) of the R, G, B channels for the sun's transmittance.
_RGB_WAVELENGTHS_UM = np.array([0.610, 0.550, 0.465])


def _unit_dirs(d: NDArray) -> NDArray[np.float64]:
    d = np.asarray(d, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"directions must have shape (..., 3), got {d.shape}")
    if not np.all(np.isfinite(d)):
        raise ValueError("directions contain NaN or Inf")
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    if np.any(norm == 0):
        raise ValueError("zero-length direction")
    return d / norm


def direction_from_angles(elevation_deg: float, azimuth_deg: float) -> NDArray[np.float64]:
    """Unit direction ``(cos e sin a, sin e, cos e cos a)``; azimuth from +Z towards +X, degrees."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])


def sun_disk_solid_angle(angular_radius: float) -> float:
    """Solid angle (sr) of a disk of angular radius ``r``: ``2 pi (1 - cos r) = 4 pi sin^2(r/2)``."""
    return 4.0 * math.pi * math.sin(0.5 * angular_radius) ** 2


def _finite_float(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def _rgb(value: Any, name: str) -> NDArray[np.float64]:
    """A non-negative finite RGB triple from a number (grey) or a 3-sequence."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        arr = np.full(3, float(value))
    else:
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number or [r, g, b], got {value!r}") from None
        if arr.shape != (3,):
            raise ValueError(f"{name} must be a number or [r, g, b], got {value!r}")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError(f"{name} must be finite and non-negative, got {value!r}")
    return arr


# --------------------------------------------------------------------------------------- sun


@dataclass(frozen=True)
class Sun:
    """The sun as an analytic light: a disk of uniform radiance.

    ``direction``: (3,) unit vector *toward* the sun, world frame.  ``radiance``: (3,) linear RGB
    disk radiance (cd/m^2-scaled).  ``angular_radius``: disk radius in radians.
    """

    direction: NDArray
    radiance: NDArray
    angular_radius: float = SUN_ANGULAR_RADIUS

    def __post_init__(self) -> None:
        d = np.asarray(self.direction, dtype=np.float64)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
            raise ValueError(f"Sun.direction must be a finite non-zero 3-vector, got {self.direction!r}")
        object.__setattr__(self, "direction", d / np.linalg.norm(d))
        object.__setattr__(self, "radiance", _rgb(self.radiance, "Sun.radiance"))
        r = _finite_float(self.angular_radius, "Sun.angular_radius")
        if not 0.0 < r < math.pi / 2:
            raise ValueError(f"Sun.angular_radius must be in (0, pi/2) radians, got {r}")
        object.__setattr__(self, "angular_radius", r)

    @property
    def solid_angle(self) -> float:
        """Solid angle of the disk, sr."""
        return sun_disk_solid_angle(self.angular_radius)

    @property
    def illuminance(self) -> NDArray[np.float64]:
        """(3,) RGB illuminance at normal incidence (lux-scaled) = radiance * disk solid angle."""
        return self.radiance * self.solid_angle

    @property
    def elevation_deg(self) -> float:
        return math.degrees(math.asin(max(-1.0, min(1.0, float(self.direction[1])))))

    @property
    def azimuth_deg(self) -> float:
        x, z = float(self.direction[0]), float(self.direction[2])
        return math.degrees(math.atan2(x, z)) if (x or z) else 0.0

    @staticmethod
    def from_illuminance(direction: NDArray, illuminance: Any, angular_radius: float = SUN_ANGULAR_RADIUS) -> "Sun":
        """A sun whose illuminance at normal incidence is ``illuminance`` (lux, number or RGB)."""
        e = _rgb(illuminance, "sun illuminance")
        r = _finite_float(angular_radius, "sun angular radius")
        if not 0.0 < r < math.pi / 2:
            raise ValueError(f"sun angular radius must be in (0, pi/2) radians, got {r}")
        return Sun(np.asarray(direction, dtype=np.float64), e / sun_disk_solid_angle(r), r)

    def spec(self) -> dict[str, Any]:
        """JSON-serializable description (manifest ``sun`` entry)."""
        return {
            "direction": [float(v) for v in self.direction],
            "radiance": [float(v) for v in self.radiance],
            "angular_radius": float(self.angular_radius),
            "illuminance": [float(v) for v in self.illuminance],
            "elevation_deg": self.elevation_deg,
            "azimuth_deg": self.azimuth_deg,
        }


def _disk_samples(direction: NDArray[np.float64], radius: float, count: int) -> NDArray[np.float64]:
    """``count`` unit directions of equal solid angle covering a disk (sunflower pattern)."""
    k = np.arange(count, dtype=np.float64)
    # cos(rho) uniform on [cos r, 1] gives equal solid angle per sample; stratified in k.
    one_minus_cos = (k + 0.5) / count * (2.0 * math.sin(0.5 * radius) ** 2)
    rho = 2.0 * np.arcsin(np.sqrt(0.5 * one_minus_cos))
    phi = k * (math.pi * (3.0 - math.sqrt(5.0)))
    w = direction
    a = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(w, a)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(w, t1)
    sr, cr = np.sin(rho), np.cos(rho)
    return (cr[:, None] * w + (sr * np.cos(phi))[:, None] * t1 + (sr * np.sin(phi))[:, None] * t2)


def splat_sun(sun: Sun, n: int, samples: int = 4096) -> NDArray[np.float64]:
    """The sun's contribution to an ``n``-texel cube, ``(6, n, n, 3)`` float64 radiance.

    The disk is cut into ``samples`` pieces of equal solid angle; each piece's share of the
    illuminance goes to the texel containing its center, divided by that texel's exact solid angle.
    Hence ``sum(result * texel_solid_angles(n)[..., None]) == sun.illuminance`` up to rounding, at
    every ``n``.  A texel fully inside the disk gets about the disk radiance.
    """
    n = _cube._check_size(n)
    pts = _disk_samples(sun.direction, sun.angular_radius, int(samples))
    face, row, col = _cube.direction_to_texel(pts, n)
    flat = (face * n + row) * n + col
    hit, counts = np.unique(flat, return_counts=True)
    share = counts.astype(np.float64) / pts.shape[0]
    out = np.zeros((6 * n * n, 3), dtype=np.float64)
    out[hit] = (share / _cube.texel_solid_angle((hit // n) % n, hit % n, n))[:, None] * sun.illuminance[None, :]
    return out.reshape(6, n, n, 3)


# --------------------------------------------------------------------------------------- skies


class Sky:
    """Base class of envcap skies.  ``sun`` is the analytic sun or ``None``."""

    sun: Sun | None = None
    supersample: int = 4

    def radiance(self, dirs: NDArray) -> NDArray[np.float64]:
        """Sky-dome radiance (linear RGB, cd/m^2-scaled) WITHOUT the sun disk, ``(..., 3)`` float64.

        ``dirs`` has shape ``(..., 3)``, any non-zero finite length (normalised here).  Finite for
        every direction, including below the horizon.
        """
        raise NotImplementedError

    def cube(self, n: int, include_sun: bool = True, supersample: int | None = None) -> NDArray[np.float32]:
        """The sky as a cube ``(6, n, n, 3)`` float32: texel averages of :meth:`radiance`
        (``supersample``^2 solid-angle-weighted samples per texel), plus, if ``include_sun``, the
        sun splatted energy-conserving (:func:`splat_sun`)."""
        ss = self.supersample if supersample is None else supersample
        out = cube_texel_average(self.radiance, n, ss, desc="sky cube")
        if include_sun and self.sun is not None:
            out = out + splat_sun(self.sun, n)
        res = out.astype(np.float32)
        if not np.all(np.isfinite(res)):  # cannot happen for valid suns; never hand out Inf
            raise ValueError("sky cube is not finite in float32 (sun radiance beyond float32 range?)")
        return res

    def spec(self) -> dict[str, Any]:
        """JSON-serializable description: ``type``, parameters, and the derived ``sun_light``."""
        raise NotImplementedError

    def _sun_light(self) -> dict[str, Any] | None:
        return None if self.sun is None else self.sun.spec()


# Preetham, Shirley, Smits 1999, appendix A.2: Perez coefficients (rows A..E) as (T, 1) pairs.
_PEREZ_Y = np.array([[0.1787, -1.4630], [-0.3554, 0.4275], [-0.0227, 5.3251], [0.1206, -2.5771], [-0.0670, 0.3703]])
_PEREZ_x = np.array([[-0.0193, -0.2592], [-0.0665, 0.0008], [-0.0004, 0.2125], [-0.0641, -0.8989], [-0.0033, 0.0452]])
_PEREZ_y = np.array([[-0.0167, -0.2608], [-0.0950, 0.0092], [-0.0079, 0.2102], [-0.0441, -1.6537], [-0.0109, 0.0529]])
# Zenith chromaticity: rows T^2, T, 1; columns theta_s^3, theta_s^2, theta_s, 1.
_ZENITH_x = np.array([[0.00166, -0.00375, 0.00209, 0.0], [-0.02903, 0.06377, -0.03202, 0.00394],
                      [0.11693, -0.21196, 0.06052, 0.25886]])
_ZENITH_y = np.array([[0.00275, -0.00610, 0.00317, 0.0], [-0.04214, 0.08970, -0.04153, 0.00516],
                      [0.15346, -0.26756, 0.06670, 0.26688]])


def _check_turbidity(t: float) -> float:
    t = _finite_float(t, "turbidity")
    if not TURBIDITY_RANGE[0] <= t <= TURBIDITY_RANGE[1]:
        raise ValueError(f"turbidity must be in [{TURBIDITY_RANGE[0]:g}, {TURBIDITY_RANGE[1]:g}], got {t:g}")
    return t


def _check_elevation(e: float, name: str = "sun elevation") -> float:
    e = _finite_float(e, name)
    if not 0.0 <= e <= 90.0:
        raise ValueError(f"{name} must be in [0, 90] degrees, got {e:g}")
    return e


def preetham_perez_coefficients(turbidity: float) -> NDArray[np.float64]:
    """Perez coefficients ``A..E`` for ``Y``, ``x``, ``y``: shape ``(3, 5)`` (paper, appendix A.2)."""
    t = _check_turbidity(turbidity)
    return np.stack([m[:, 0] * t + m[:, 1] for m in (_PEREZ_Y, _PEREZ_x, _PEREZ_y)])


def preetham_zenith(turbidity: float, sun_zenith: float) -> tuple[float, float, float]:
    """Zenith luminance (cd/m^2) and chromaticity ``(Y_z, x_z, y_z)``; ``sun_zenith`` in radians.

    ``Y_z = 1000 [(4.0453 T - 4.9710) tan(chi) - 0.2155 T + 2.4192]`` with
    ``chi = (4/9 - T/120)(pi - 2 theta_s)`` (the paper gives kcd/m^2); ``x_z``, ``y_z`` are the
    paper's cubic polynomials in ``theta_s`` with quadratic dependence on ``T``.
    """
    t = _check_turbidity(turbidity)
    ts = _finite_float(sun_zenith, "sun zenith")
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
    t = _check_turbidity(turbidity)
    e = _check_elevation(elevation_deg)
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
        self.turbidity = _check_turbidity(turbidity)
        self.sun_elevation_deg = _check_elevation(sun_elevation_deg)
        self.sun_azimuth_deg = _finite_float(sun_azimuth_deg, "sun azimuth")
        self.scale = _finite_float(scale, "scale")
        if self.scale < 0:
            raise ValueError(f"scale must be non-negative, got {self.scale:g}")
        self.ground_albedo = _finite_float(ground_albedo, "ground albedo")
        if not 0.0 <= self.ground_albedo <= 1.0:
            raise ValueError(f"ground albedo must be in [0, 1], got {self.ground_albedo:g}")
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
        d = _unit_dirs(dirs)
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
            "sun_light": self._sun_light(),
        }


class UniformSky(Sky):
    """Constant radiance in every direction (tests), with an optional analytic sun."""

    def __init__(self, radiance: Any, sun: Sun | None = None, sun_table: dict | None = None) -> None:
        self.value = _rgb(radiance, "uniform sky radiance")
        self.sun = sun
        self._sun_table = sun_table

    def radiance(self, dirs: NDArray) -> NDArray[np.float64]:
        d = _unit_dirs(dirs)
        return np.broadcast_to(self.value, d.shape).copy()

    def cube(self, n: int, include_sun: bool = True, supersample: int | None = None) -> NDArray[np.float32]:
        return super().cube(n, include_sun, 1 if supersample is None else supersample)

    def spec(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "uniform", "radiance": [float(v) for v in self.value]}
        if self._sun_table is not None:
            out["sun"] = dict(self._sun_table)
        out["sun_light"] = self._sun_light()
        return out


class LatLongSky(Sky):
    """A lat-long HDR image (``(H, W, 3)``, OpenEXR LatLong convention) times ``scale``.

    The image should not contain the sun if an analytic ``sun`` is given (it would count twice).
    """

    def __init__(self, image: NDArray, scale: float = 1.0, sun: Sun | None = None, file: str | None = None,
                 sun_table: dict | None = None) -> None:
        img = np.asarray(image, dtype=np.float32)
        if img.ndim != 3 or img.shape[2] != 3 or img.shape[1] != 2 * img.shape[0]:
            raise ValueError(f"lat-long sky image must have shape (H, 2H, 3), got {img.shape}")
        if not np.all(np.isfinite(img)) or np.any(img < 0):
            raise ValueError("lat-long sky image contains NaN, Inf or negative values")
        self.image = img
        self.scale = _finite_float(scale, "scale")
        if self.scale < 0:
            raise ValueError(f"scale must be non-negative, got {self.scale:g}")
        self.sun = sun
        self.file = file
        self._sun_table = sun_table

    def radiance(self, dirs: NDArray) -> NDArray[np.float64]:
        return sample_latlong(self.image, _unit_dirs(dirs)) * self.scale

    def cube(self, n: int, include_sun: bool = True, supersample: int | None = None) -> NDArray[np.float32]:
        out = latlong_to_cube(self.image, n, supersample).astype(np.float64) * self.scale
        if include_sun and self.sun is not None:
            out = out + splat_sun(self.sun, n)
        return out.astype(np.float32)

    def spec(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "latlong", "file": self.file, "scale": self.scale}
        if self._sun_table is not None:
            out["sun"] = dict(self._sun_table)
        out["sun_light"] = self._sun_light()
        return out


# --------------------------------------------------------------------------------------- specs

_SPEC_KEYS = {
    "preetham": ({"type", "turbidity", "sun_elevation_deg"},
                 {"sun_azimuth_deg", "scale", "ground_albedo", "sun_light"}),
    "latlong": ({"type", "file"}, {"scale", "sun", "sanitize", "sun_light"}),
    "uniform": ({"type", "radiance"}, {"sun", "sun_light"}),
}
_SUN_KEYS = ({"elevation_deg", "illuminance"}, {"azimuth_deg", "angular_radius_deg"})


def _check_keys(table: dict, required: set[str], optional: set[str], where: str) -> None:
    if not isinstance(table, dict):
        raise ValueError(f"{where} must be a table, got {type(table).__name__}")
    unknown = sorted(set(table) - required - optional)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(required | optional)}")
    missing = sorted(required - set(table))
    if missing:
        raise ValueError(f"{where}: missing key(s) {missing}")


def _sun_from_table(table: dict, where: str) -> Sun:
    _check_keys(table, *_SUN_KEYS, where)
    e = _check_elevation(table["elevation_deg"], f"{where}.elevation_deg")
    a = _finite_float(table.get("azimuth_deg", 0.0), f"{where}.azimuth_deg")
    r = math.radians(_finite_float(table.get("angular_radius_deg", math.degrees(SUN_ANGULAR_RADIUS)),
                                   f"{where}.angular_radius_deg"))
    return Sun.from_illuminance(direction_from_angles(e, a), table["illuminance"], r)


def sky_from_spec(spec: dict, base_dir: Path | None = None) -> Sky:
    """Build a sky from a scene's ``[sky]`` table (or a :meth:`Sky.spec` output).

    Kinds::

        {"type": "preetham", "turbidity": 3.0, "sun_elevation_deg": 35, "sun_azimuth_deg": 120,
         "scale": 1.0, "ground_albedo": 0.2}
        {"type": "latlong", "file": "sky.exr", "scale": 1.0, "sanitize": false,
         "sun": {"elevation_deg": 40, "azimuth_deg": 0, "illuminance": 90000 or [r, g, b],
                 "angular_radius_deg": 0.2665}}
        {"type": "uniform", "radiance": [r, g, b], "sun": {...}}

    Relative ``file`` names resolve against ``base_dir``.  ``sun_light`` (written by
    :meth:`Sky.spec`) is derived: it is accepted only if it matches what the other keys give.
    Unknown keys or types raise ``ValueError`` naming them.
    """
    if not isinstance(spec, dict):
        raise ValueError(f"sky spec must be a table, got {type(spec).__name__}")
    kind = spec.get("type")
    if kind not in _SPEC_KEYS:
        raise ValueError(f"sky: unknown type {kind!r}; known: {sorted(_SPEC_KEYS)}")
    _check_keys(spec, *_SPEC_KEYS[kind], f"sky ({kind})")
    sky: Sky
    if kind == "preetham":
        sky = PreethamSky(spec["turbidity"], spec["sun_elevation_deg"], spec.get("sun_azimuth_deg", 0.0),
                          spec.get("scale", 1.0), spec.get("ground_albedo", DEFAULT_GROUND_ALBEDO))
    else:
        sun_table = spec.get("sun")
        sun = None if sun_table is None else _sun_from_table(sun_table, "sky.sun")
        if kind == "uniform":
            sky = UniformSky(spec["radiance"], sun, sun_table)
        else:
            file = spec["file"]
            if not isinstance(file, str) or not file:
                raise ValueError(f"sky.file must be a non-empty string, got {file!r}")
            path = Path(file)
            if not path.is_absolute() and base_dir is not None:
                path = Path(base_dir) / path
            sanitize = spec.get("sanitize", False)
            if not isinstance(sanitize, bool):
                raise ValueError(f"sky.sanitize must be true or false, got {sanitize!r}")
            sky = LatLongSky(load_latlong(path, sanitize=sanitize), spec.get("scale", 1.0), sun, file, sun_table)
    given = spec.get("sun_light")
    if given is not None or "sun_light" in spec:
        want = sky._sun_light()
        if (given is None) != (want is None) or (want is not None and not _close_tables(given, want)):
            raise ValueError("sky.sun_light is derived from the other keys and does not match them; "
                             "edit the sun parameters instead (or drop sun_light)")
    return sky


def _close_tables(a: Any, b: dict) -> bool:
    if not isinstance(a, dict) or set(a) != set(b):
        return False
    for k, v in b.items():
        try:
            if not np.allclose(np.asarray(a[k], dtype=np.float64), np.asarray(v, dtype=np.float64),
                               rtol=1e-9, atol=1e-12):
                return False
        except (TypeError, ValueError):
            return False
    return True
