"""What a sky is (:class:`Sky`) and what a sky model declares to the registry (:class:`SkyModel`).

Units and conventions (derivation and decisions: ``docs/sky.md``)
-----------------------------------------------------------------
* Radiance is linear Rec.709 RGB scaled so that the luminance ``Y = 0.2126 R + 0.7152 G +
  0.0722 B`` is in cd/m^2 (for the Preetham sky; a lat-long file is taken in its own units times
  ``scale``).  Illuminance is then in lux (lm/m^2).
* World frame right-handed, +Y up.  A direction of elevation ``e`` and azimuth ``a`` is
  ``(cos e sin a, sin e, cos e cos a)``: azimuth is measured from +Z towards +X (it equals the
  lat-long longitude of :mod:`envcap.core.latlong`; azimuth 90 deg is +X).
* The sun is kept twice (lead's decision): as an analytic :class:`~envcap.sky.sun.Sun` (direction,
  disk radiance, angular radius, illuminance at normal incidence) for manifests and direct
  lighting, and splatted into float32 sky cubes so that ``sum(texel radiance * texel solid angle)``
  over the sun's contribution equals ``Sun.illuminance`` at any cube size (N = 1 included).
  Nothing is clipped: values up to ~1e12 are finite in float32 (they are not in float16;
  half-float consumers must take the sun from the manifest instead).
* :meth:`Sky.radiance` is the dome *without* the sun disk, finite for every direction.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from envcap.core.latlong import cube_texel_average
from envcap.sky.sun import Sun, splat_sun


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
        sun splatted energy-conserving (:func:`~envcap.sky.sun.splat_sun`)."""
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

    def sun_light(self) -> dict[str, Any] | None:
        """The derived ``sun_light`` entry of :meth:`spec`: :meth:`Sun.spec` or ``None``."""
        return None if self.sun is None else self.sun.spec()


@dataclass(frozen=True)
class SkyModel:
    """A sky type of the scene's ``[sky]`` table, as registered in :mod:`envcap.sky.registry`.

    ``name``: the ``type`` value that selects it.  ``required``: the keys it needs (besides
    ``type``); ``optional``: its other parameters (``sun_light`` is accepted for every model).
    ``parse(table, base_dir)`` turns the key-checked table into the model's typed parameters (a
    frozen dataclass documented in the model's module; relative file names resolve against
    ``base_dir``); ``build(params)`` makes the :class:`Sky`.  Both raise ``ValueError`` naming the
    bad key.
    """

    name: str
    required: frozenset[str]
    optional: frozenset[str]
    parse: Callable[[dict[str, Any], Path | None], Any]
    build: Callable[[Any], Sky]
