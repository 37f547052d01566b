"""The evaluator's truth: fresh captures at evaluation positions, composited with the sky like the
runtime, filtered at exactly each evaluated lobe power.

Conventions: cubes ``(6, N, N, C)`` (``envcap/core/cube.py``), linear HDR, premultiplied street
RGBA (alpha 0 where the sky shows); ``w = inf`` is the mirror (unfiltered).  The truth of a street
at any angle is captured with its cube axes along the street's frame (``yaw_deg``,
:mod:`envcap.core.street_frame`), the sky cube turned the same way (texel ``d`` holds the sky
along the world direction ``R^T d``).  Definitions and measured accuracy: ``docs/evaluation.md``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any, Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.capture.renderer import CubeCapture
from envcap.core import cube as cubemod
from envcap.core.latlong import cube_texel_average
from envcap.core.street_frame import from_frame, to_frame
from envcap.core.lobes import LobeLadder, texel_power
from envcap.prefilter import convolve_exact, convolve_exact_dirs, omega_box_pyramid, prefilter_chain
from envcap.probeset.shadow_fit import shadow_effect_parameters
from envcap.runtime.sampling import composite

TRUTH_TEXELS_PER_SIGMA = 3.0
"""Minimum source texels (face-center angle 2/S) per lobe RMS angle for the box-reduced truth."""


def truth_grid_size(w: float, n: int, min_grid: int = 8) -> int:
    """Face size of the grid a lobe of power ``w`` is compared on, for an ``n``-texel capture.

    ``n >> k`` for the largest ``k >= 1`` with ``n >> k >= max(0.9 sqrt(w + 2), min_grid)``: the
    lobe ladder's density (a face-center texel, ``2/M`` rad, spans about two lobe RMS angles
    ``1/sqrt(w + 2)``), so a ladder power ``w_k`` gets its own level's grid ``N_k``; at most
    ``n // 2``; ``n`` for the mirror.
    """
    if math.isinf(w):
        return n
    target = max(0.9 * math.sqrt(w + 2.0), float(min_grid))
    k = 1
    while (n >> (k + 1)) >= target:
        k += 1
    return max(n >> k, 1)


def filter_truth(cube: NDArray, w: float, quality: str = "default", ctx: Any = None,
                 min_grid: int = 8) -> NDArray[np.float32]:
    """``cube`` ``(6, N, N, C)`` filtered with the normalized ``cos^w`` lobe onto the grid of
    :func:`truth_grid_size` (``(6, M, M, C)``), at exactly ``w``.

    * Wide lobes (a solid-angle box reduction of ``cube`` of size ``S < N`` with at least
      :data:`TRUTH_TEXELS_PER_SIGMA` texels per lobe RMS angle exists): the float64 reference
      :func:`envcap.prefilter.exact.convolve_exact_dirs` over that reduction (no footprint truncation;
      the box adds at most ``1 / (12 * 3^2 / 4)`` ~ 1 % to the lobe's angular variance).
    * Otherwise the GLSL chain filter from the full-resolution cube, with a ladder whose last
      level is ``w`` (its other levels are made needle-sharp, i.e. cheap; the last level only
      depends on the input, so a ladder power of the bake is reproduced bit for bit).
    * ``w`` at or above the texel power of ``N``: the float64 reference at full resolution.
    """
    n = cube.shape[1]
    m = truth_grid_size(w, n, min_grid)
    k = 0
    while max(n >> k, 1) != m:
        k += 1
    need = TRUTH_TEXELS_PER_SIGMA * 2.0 * math.sqrt(w + 2.0)   # S >= texels * (2 / S) per sigma
    pyr = omega_box_pyramid(cube, k + 1)
    coarse = [p for p in pyr[1:] if p.shape[1] >= need and p.shape[1] >= m]
    if coarse:
        src = coarse[-1]
        return convolve_exact_dirs(src, w, cubemod.texel_directions(m)).astype(np.float32)
    tp = texel_power(n)
    if k < 1 or not w < tp - k:
        return convolve_exact(cube, w, m).astype(np.float32)
    powers = [tp - i for i in range(k)] + [float(w)]
    sizes = tuple(max(n >> i, 1) for i in range(k + 1))
    return prefilter_chain(cube, LobeLadder(sizes, tuple(powers)), quality=quality, ctx=ctx, progress=False)[-1]


def framed_sky_cube(sky: Any, n: int, yaw_deg: float, include_sun: bool = True) -> NDArray[np.float32]:
    """``sky.cube(n, include_sun)`` with its faces along the frame of a street at ``yaw_deg``:
    texel ``d`` averages the sky radiance along the world direction ``R^T d``, the sun splatted at
    its direction in the frame.  ``yaw_deg = 0``: exactly ``sky.cube``."""
    if yaw_deg == 0.0:
        return sky.cube(n, include_sun=include_sun)
    from envcap.sky.sun import splat_sun
    out = cube_texel_average(lambda d: sky.radiance(from_frame(d, yaw_deg)), n, sky.supersample)
    if include_sun and sky.sun is not None:
        out = out + splat_sun(dataclasses.replace(sky.sun, direction=to_frame(sky.sun.direction, yaw_deg)), n)
    return out.astype(np.float32)


def with_alpha(rgb: NDArray) -> NDArray[np.float32]:
    """``(..., 3)`` colors with an opaque alpha channel appended, ``(..., 4)`` float32 (a sky cube as RGBA)."""
    return np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,), rgb.dtype)], axis=-1).astype(np.float32)


class TruthRenderer:
    """Fresh captures at evaluation positions, composited with the sky like the runtime.

    :meth:`filtered` returns ``{w: {"street": (6, M, M, 4), "sky": (6, M, M, 4),
    "sky_nosun": ...}}`` filtered separately at exactly ``w``; the truth is
    ``composite(street, sky)`` (``street.rgb + (1 - clamp(alpha)) * sky``, what the runtime
    computes from a chain).  :meth:`physical` filters the composite itself (the radiance that
    really arrives), to measure what compositing after filtering costs.  ``times``: seconds spent
    capturing (``capture_s``) and filtering (``filter_s``).  ``yaw_deg`` (every method): the cube
    axes of a street at any angle (its frame; 0: the world's), the sky turned with them.
    """

    def __init__(self, scene: Any, resolution: int, ctx: Any, quality: str = "default") -> None:
        self.n = int(resolution)
        self.ctx = ctx
        self.quality = quality
        self.sky = scene.sky.build()
        self.sky_rgba = {True: with_alpha(self.sky.cube(self.n)), False: with_alpha(self.sky.cube(self.n, include_sun=False))}
        self._sky_cache: dict[tuple[float, bool, float], NDArray] = {}
        self._sky_turned: dict[tuple[bool, float], NDArray[np.float32]] = {}
        # the sun shadows of the bake (the scene's [shadows]: fit, texel, cascades), not the default map
        self.cap = CubeCapture.from_scene(scene, self.n, sky=self.sky, ctx=ctx,
                                          effect_parameters=shadow_effect_parameters(scene))
        self.times = {"capture_s": 0.0, "filter_s": 0.0}

    def release(self) -> None:
        self.cap.release()

    def capture(self, position: Sequence[float], yaw_deg: float = 0.0) -> Any:
        """A capture at ``position`` (3,) m: ``rgba`` ``(6, N, N, 4)``, ``distance`` ``(6, N, N)`` m."""
        t0 = time.perf_counter()
        c = self.cap.capture(position, yaw_deg=yaw_deg) if yaw_deg else self.cap.capture(position)
        self.times["capture_s"] += time.perf_counter() - t0
        return c

    def sky_cube(self, sun: bool, yaw_deg: float = 0.0) -> NDArray[np.float32]:
        """The unfiltered sky RGBA ``(6, N, N, 4)`` (with or without the sun) in the axes of ``yaw_deg``."""
        if yaw_deg == 0.0:
            return self.sky_rgba[sun]
        if (sun, yaw_deg) not in self._sky_turned:
            self._sky_turned[(sun, yaw_deg)] = with_alpha(framed_sky_cube(self.sky, self.n, yaw_deg, sun))
        return self._sky_turned[(sun, yaw_deg)]

    def sky_at(self, w: float, sun: bool, yaw_deg: float = 0.0) -> NDArray[np.float64]:
        """The sky (with or without the sun) filtered at ``w``, cached."""
        if math.isinf(w):
            return self.sky_cube(sun, yaw_deg).astype(np.float64)
        if (w, sun, yaw_deg) not in self._sky_cache:
            self._sky_cache[(w, sun, yaw_deg)] = filter_truth(self.sky_cube(sun, yaw_deg), w, self.quality,
                                                              self.ctx).astype(np.float64)
        return self._sky_cache[(w, sun, yaw_deg)]

    def filtered(self, rgba: NDArray, powers: Sequence[float],
                 yaw_deg: float = 0.0) -> dict[float, dict[str, NDArray[np.float64]]]:
        """Street RGBA ``rgba`` and both skies filtered at each of ``powers``."""
        t0 = time.perf_counter()
        out: dict[float, dict[str, NDArray[np.float64]]] = {}
        for w in powers:
            st = rgba.astype(np.float64) if math.isinf(w) else filter_truth(rgba, w, self.quality, self.ctx).astype(np.float64)
            out[w] = {"street": st, "sky": self.sky_at(w, True, yaw_deg), "sky_nosun": self.sky_at(w, False, yaw_deg)}
        self.times["filter_s"] += time.perf_counter() - t0
        return out

    def physical(self, rgba: NDArray, w: float, sun: bool = True, yaw_deg: float = 0.0) -> NDArray[np.float64]:
        """The composite radiance ``rgb + (1 - alpha) sky`` filtered at ``w`` (``(6, M, M, 3)``)."""
        comp = composite(rgba.astype(np.float64), self.sky_cube(sun, yaw_deg))
        return comp if math.isinf(w) else filter_truth(comp, w, self.quality, self.ctx).astype(np.float64)
