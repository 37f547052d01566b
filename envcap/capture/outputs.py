"""What a capture returns: one probe (:class:`ProbeCapture`) or a set (:class:`CaptureSet`).

Per probe, arrays indexed ``[face, row = t, column = s]`` in the cube convention of
:mod:`envcap.core.cube`, face resolution ``N``:

* ``rgba``: ``(6, N, N, 4)`` float32, linear HDR radiance, premultiplied alpha: alpha 1 where
  geometry is seen, 0 (and RGB 0) where the sky shows.
* ``distance``: ``(6, N, N)`` float32, radial (Euclidean) distance in meters from the probe
  center to the surface seen through the texel center; 0 where alpha is 0.
* ``backfacing``: ``(6, N, N)`` bool, the texel sees the unlit side of a surface (back face,
  radiance 0).  A probe inside a closed building sees only back faces
  (:func:`probe_inside_geometry`).

``passes_run`` names the passes in the order they ran: the per-set passes of the effects that
have one (e.g. ``sky_sh``, ``shadow_map``), then ``render`` (the six face draws) and
``readback`` (one read of all faces); ``pass_times_s`` their wall seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube


def probe_inside_geometry(backfacing: NDArray[np.bool_], threshold: float = 0.25) -> bool:
    """True when more than ``threshold`` of the sphere (solid-angle weighted) sees back faces.

    ``backfacing`` is ``(6, N, N)`` bool (:attr:`ProbeCapture.backfacing`).  Seen from inside a
    closed building every texel sees a back face (fraction 1); from outside, only meshes with
    wrong normals or open shells show any.
    """
    b = np.asarray(backfacing, dtype=bool)
    cube.check_cube(b[..., None], "backfacing")
    w = cube.texel_solid_angles(b.shape[1])
    return bool(np.sum(w * b) / (4.0 * math.pi) > threshold)


@dataclass
class ProbeCapture:
    """One captured probe.  Arrays per the module docstring; ``position`` (3,) meters."""

    position: NDArray[np.float64]
    rgba: NDArray[np.float32]
    distance: NDArray[np.float32]
    backfacing: NDArray[np.bool_]
    passes_run: list[str]
    pass_times_s: dict[str, float]
    draw_stats: dict[str, float] = field(default_factory=dict)
    """``cull_s`` (CPU seconds choosing chunks), ``triangles`` (drawn, summed over the six faces),
    ``draw_calls`` (summed over the faces)."""

    @property
    def inside_geometry(self) -> bool:
        """:func:`probe_inside_geometry` of :attr:`backfacing`."""
        return probe_inside_geometry(self.backfacing)


@dataclass
class CaptureSet:
    """Probes captured with one :class:`~envcap.capture.renderer.CubeCapture`: arrays with a
    leading probe axis ``P``.

    ``rgba`` (P, 6, N, N, 4), ``distance`` (P, 6, N, N), ``backfacing`` (P, 6, N, N),
    ``positions`` (P, 3).  ``pass_times_s`` sums each pass over the set (per-set passes once).
    """

    positions: NDArray[np.float64]
    rgba: NDArray[np.float32]
    distance: NDArray[np.float32]
    backfacing: NDArray[np.bool_]
    passes_run: list[str]
    pass_times_s: dict[str, float] = field(default_factory=dict)
