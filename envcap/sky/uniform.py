"""A sky of constant radiance, for tests (``[sky] type = "uniform"``).

Scene parameters (``[sky]`` keys; errors name the key):

* ``radiance`` (required): linear RGB radiance, cd/m^2-scaled, in [0, 10^12]
  (:data:`envcap.sky.checks.RGB_LIMIT`); a number means grey.
* ``sun`` (optional): an analytic sun, the table of :class:`envcap.sky.sun.SunTable`
  (``elevation_deg``, ``illuminance`` in lux, ``azimuth_deg``, ``angular_radius_deg``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.sky.base import Sky, SkyModel
from envcap.core.checks import unit_directions
from envcap.sky.checks import RGB_LIMIT, rgb_triple
from envcap.sky.sun import Sun, SunTable


class UniformSky(Sky):
    """Constant radiance in every direction (tests), with an optional analytic sun.

    ``sun_table`` is the scene's ``sun`` sub-table as written, echoed by :meth:`spec`.
    """

    def __init__(self, radiance: Any, sun: Sun | None = None, sun_table: dict | None = None) -> None:
        self.value = rgb_triple(radiance, "uniform sky radiance")
        self.sun = sun
        self.sun_table = sun_table

    def radiance(self, dirs: NDArray) -> NDArray[np.float64]:
        d = unit_directions(dirs)
        return np.broadcast_to(self.value, d.shape).copy()

    def cube(self, n: int, include_sun: bool = True, supersample: int | None = None) -> NDArray[np.float32]:
        return super().cube(n, include_sun, 1 if supersample is None else supersample)

    def spec(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "uniform", "radiance": [float(v) for v in self.value]}
        if self.sun_table is not None:
            out["sun"] = dict(self.sun_table)
        out["sun_light"] = self.sun_light()
        return out


@dataclass(frozen=True)
class UniformParams:
    """The checked ``[sky]`` parameters of a uniform sky: ``radiance`` (3,) RGB and the ``sun``."""

    radiance: tuple[float, float, float]
    sun: SunTable | None = None

    @classmethod
    def parse(cls, table: dict[str, Any], base_dir: Path | None = None) -> "UniformParams":
        """Check the values of a key-checked ``[sky]`` table (``base_dir`` is unused: no files)."""
        sun = None if table.get("sun") is None else SunTable.parse(table["sun"], "sky.sun")
        radiance = rgb_triple(table["radiance"], "sky.radiance", RGB_LIMIT)
        return cls(tuple(float(v) for v in radiance), sun)

    def build(self) -> UniformSky:
        sun = None if self.sun is None else self.sun.sun()
        return UniformSky(self.radiance, sun, None if self.sun is None else self.sun.table)


UNIFORM = SkyModel(
    name="uniform",
    required=frozenset({"radiance"}),
    optional=frozenset({"sun"}),
    parse=UniformParams.parse,
    build=UniformParams.build,
)
"""The registry entry of the uniform sky."""
