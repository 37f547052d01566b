"""The sun: an analytic disk light, its ``sun`` table in a scene's ``[sky]``, and its splat into cubes.

Conventions (see :mod:`envcap.sky.base` and ``docs/sky.md``): world frame right-handed, +Y up; a
direction of elevation ``e`` and azimuth ``a`` is ``(cos e sin a, sin e, cos e cos a)`` (azimuth
from +Z towards +X, the lat-long longitude of :mod:`envcap.core.latlong`).  Radiance is linear
Rec.709 RGB in cd/m^2-scaled units, illuminance in lux.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.checks import check_table_keys, finite_float, positive_int
from envcap.core.cube import direction_to_texel, texel_solid_angle
from envcap.sky.checks import RGB_LIMIT, check_azimuth, check_elevation, rgb_triple

SUN_ANGULAR_RADIUS: float = math.radians(0.2665)
"""Angular radius of the solar disk, radians (0.2665 deg, mean Earth-Sun distance)."""

SOLAR_ILLUMINANCE_EXTRATERRESTRIAL: float = 128_000.0
"""Solar illuminance at normal incidence outside the atmosphere, lux (the daylighting literature's
value 127.5-133 klx; 128 klx used here)."""


def direction_from_angles(elevation_deg: float, azimuth_deg: float) -> NDArray[np.float64]:
    """Unit direction ``(cos e sin a, sin e, cos e cos a)``; azimuth from +Z towards +X, degrees."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])


def sun_disk_solid_angle(angular_radius: float) -> float:
    """Solid angle (sr) of a disk of angular radius ``r``: ``2 pi (1 - cos r) = 4 pi sin^2(r/2)``."""
    return 4.0 * math.pi * math.sin(0.5 * angular_radius) ** 2


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
        object.__setattr__(self, "radiance", rgb_triple(self.radiance, "Sun.radiance"))
        r = finite_float(self.angular_radius, "Sun.angular_radius")
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
        """Elevation of the disk center above the horizon, degrees."""
        return math.degrees(math.asin(max(-1.0, min(1.0, float(self.direction[1])))))

    @property
    def azimuth_deg(self) -> float:
        """Azimuth of the disk center, degrees from +Z towards +X (0 when the sun is at the zenith)."""
        x, z = float(self.direction[0]), float(self.direction[2])
        return math.degrees(math.atan2(x, z)) if (x or z) else 0.0

    @staticmethod
    def from_illuminance(direction: NDArray, illuminance: Any, angular_radius: float = SUN_ANGULAR_RADIUS) -> "Sun":
        """A sun whose illuminance at normal incidence is ``illuminance`` (lux, number or RGB)."""
        e = rgb_triple(illuminance, "sun illuminance")
        r = finite_float(angular_radius, "sun angular radius")
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


@dataclass(frozen=True)
class SunTable:
    """A sky's ``sun`` sub-table (uniform and lat-long skies), checked.

    ``elevation_deg`` in [0, 90], ``azimuth_deg`` from +Z towards +X in [-360, 360] (default 0),
    ``illuminance`` (3,) RGB lux at normal incidence in [0, 10^12] (:data:`~envcap.sky.checks.RGB_LIMIT`),
    ``angular_radius_deg`` in (0, 90) (default 0.2665).
    ``table`` is the sub-table exactly as written; skies echo it in :meth:`Sky.spec` (manifests).
    """

    elevation_deg: float
    azimuth_deg: float
    illuminance: tuple[float, float, float]
    angular_radius_deg: float
    table: dict[str, Any]

    REQUIRED = frozenset({"elevation_deg", "illuminance"})
    OPTIONAL = frozenset({"azimuth_deg", "angular_radius_deg"})

    @classmethod
    def parse(cls, table: Any, where: str) -> "SunTable":
        """Check ``table`` (keys, ranges); errors name ``where`` (e.g. ``"sky.sun"``)."""
        check_table_keys(table, set(cls.REQUIRED), set(cls.OPTIONAL), where)
        e = check_elevation(table["elevation_deg"], f"{where}.elevation_deg")
        a = check_azimuth(table.get("azimuth_deg", 0.0), f"{where}.azimuth_deg")
        r_deg = finite_float(table.get("angular_radius_deg", math.degrees(SUN_ANGULAR_RADIUS)),
                             f"{where}.angular_radius_deg")
        illuminance = rgb_triple(table["illuminance"], f"{where}.illuminance", RGB_LIMIT)
        cls._sun(e, a, illuminance, r_deg)  # the radius range, with the message Sun gives
        return cls(e, a, tuple(float(v) for v in illuminance), r_deg, dict(table))

    def sun(self) -> Sun:
        """The analytic :class:`Sun` this table describes."""
        return self._sun(self.elevation_deg, self.azimuth_deg, np.asarray(self.illuminance), self.angular_radius_deg)

    @staticmethod
    def _sun(e: float, a: float, illuminance: NDArray[np.float64], r_deg: float) -> Sun:
        return Sun.from_illuminance(direction_from_angles(e, a), illuminance, math.radians(r_deg))


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
    n = positive_int(n, "cube face size")
    pts = _disk_samples(sun.direction, sun.angular_radius, int(samples))
    face, row, col = direction_to_texel(pts, n)
    flat = (face * n + row) * n + col
    hit, counts = np.unique(flat, return_counts=True)
    share = counts.astype(np.float64) / pts.shape[0]
    out = np.zeros((6 * n * n, 3), dtype=np.float64)
    out[hit] = (share / texel_solid_angle((hit // n) % n, hit % n, n))[:, None] * sun.illuminance[None, :]
    return out.reshape(6, n, n, 3)
