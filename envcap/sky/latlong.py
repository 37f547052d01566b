"""A sky from a lat-long HDR image file (``[sky] type = "latlong"``).

Scene parameters (``[sky]`` keys; errors name the key):

* ``file`` (required): the image (OpenEXR LatLong convention, see :mod:`envcap.core.latlong`),
  relative to the scene file's directory unless absolute.  Radiance is taken in the file's units.
* ``scale`` (default 1): factor on the image, in [0, 10^6] (:data:`envcap.sky.checks.SCALE_LIMIT`);
  the scaled image must stay at most :data:`envcap.sky.checks.RGB_LIMIT`.
* ``sanitize`` (default false): replace NaN / Inf / negative texels instead of rejecting the file.
* ``sun`` (optional): an analytic sun, the table of :class:`envcap.sky.sun.SunTable`.  The image
  should not contain the sun then (it would count twice).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.latlong import latlong_to_cube, load_latlong, sample_latlong
from envcap.sky.base import Sky, SkyModel
from envcap.core.checks import unit_directions
from envcap.sky.checks import RGB_LIMIT, check_scale
from envcap.sky.sun import Sun, SunTable, splat_sun


class LatLongSky(Sky):
    """A lat-long HDR image (``(H, W, 3)``, OpenEXR LatLong convention) times ``scale``.

    The image should not contain the sun if an analytic ``sun`` is given (it would count twice).
    ``file`` (the name as the scene wrote it) and ``sun_table`` (the ``sun`` sub-table as written)
    are echoed by :meth:`spec`.
    """

    def __init__(self, image: NDArray, scale: float = 1.0, sun: Sun | None = None, file: str | None = None,
                 sun_table: dict | None = None) -> None:
        img = np.asarray(image, dtype=np.float32)
        if img.ndim != 3 or img.shape[2] != 3 or img.shape[1] != 2 * img.shape[0]:
            raise ValueError(f"lat-long sky image must have shape (H, 2H, 3), got {img.shape}")
        if not np.all(np.isfinite(img)) or np.any(img < 0):
            raise ValueError("lat-long sky image contains NaN, Inf or negative values")
        self.image = img
        self.scale = check_scale(scale)
        self.sun = sun
        self.file = file
        self.sun_table = sun_table

    def radiance(self, dirs: NDArray) -> NDArray[np.float64]:
        return sample_latlong(self.image, unit_directions(dirs)) * self.scale

    def cube(self, n: int, include_sun: bool = True, supersample: int | None = None) -> NDArray[np.float32]:
        out = latlong_to_cube(self.image, n, supersample).astype(np.float64) * self.scale
        if include_sun and self.sun is not None:
            out = out + splat_sun(self.sun, n)
        return out.astype(np.float32)

    def spec(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": "latlong", "file": self.file, "scale": self.scale}
        if self.sun_table is not None:
            out["sun"] = dict(self.sun_table)
        out["sun_light"] = self.sun_light()
        return out


@dataclass(frozen=True)
class LatLongParams:
    """The checked ``[sky]`` parameters of a lat-long sky.

    ``file`` as written (echoed in manifests), ``path`` the file resolved against the scene's
    directory, ``scale``, ``sanitize`` and the ``sun``.  The image is read by :meth:`build`.
    """

    file: str
    path: Path
    scale: float = 1.0
    sanitize: bool = False
    sun: SunTable | None = None

    @classmethod
    def parse(cls, table: dict[str, Any], base_dir: Path | None = None) -> "LatLongParams":
        """Check the values of a key-checked ``[sky]`` table; a relative ``file`` joins ``base_dir``."""
        sun = None if table.get("sun") is None else SunTable.parse(table["sun"], "sky.sun")
        file = table["file"]
        if not isinstance(file, str) or not file:
            raise ValueError(f"sky.file must be a non-empty string, got {file!r}")
        path = Path(file)
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
        sanitize = table.get("sanitize", False)
        if not isinstance(sanitize, bool):
            raise ValueError(f"sky.sanitize must be true or false, got {sanitize!r}")
        return cls(file, path, check_scale(table.get("scale", 1.0), "sky.scale"), sanitize, sun)

    def build(self) -> LatLongSky:
        """Read the image (``FileNotFoundError`` / ``ValueError`` naming the file) and make the sky;
        the scaled image must stay at most :data:`~envcap.sky.checks.RGB_LIMIT`."""
        sun = None if self.sun is None else self.sun.sun()
        image = load_latlong(self.path, sanitize=self.sanitize)
        peak = float(np.max(image)) * self.scale if image.size else 0.0
        if not peak <= RGB_LIMIT:
            raise ValueError(f"sky.scale: {self.path} peaks at {float(np.max(image)):g}, times scale {self.scale:g} "
                             f"is past the radiance limit of {RGB_LIMIT:g}; lower sky.scale")
        return LatLongSky(image, self.scale, sun, self.file, None if self.sun is None else self.sun.table)


LATLONG = SkyModel(
    name="latlong",
    required=frozenset({"file"}),
    optional=frozenset({"scale", "sanitize", "sun"}),
    parse=LatLongParams.parse,
    build=LatLongParams.build,
)
"""The registry entry of the lat-long sky."""
