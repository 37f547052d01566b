"""The crowd's camera: a pinhole looking along the street over the walkers' span.

Matrices are float64 ``(4, 4)`` for column vectors, in the render frame (world minus the render
origin, m); OpenGL clip conventions (``z`` in [-1, 1], right-handed view looking down -Z).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from envcap.core.view_matrices import look_at, perspective

EYE_HEIGHT = 4.0
"""Camera height (m) above the ground of the span's start."""
FOV_Y_DEG = 50.0
"""Vertical field of view."""
NEAR, FAR = 0.1, 5000.0
"""Clip planes (m)."""


@dataclass(frozen=True)
class Camera:
    """``eye`` (3,) and ``target`` (3,) in the render frame (m), ``aspect`` width / height."""

    eye: NDArray[np.float64]
    target: NDArray[np.float64]
    aspect: float
    fov_y_deg: float = FOV_Y_DEG

    def view(self) -> NDArray[np.float64]:
        """World-to-view matrix."""
        return look_at(self.eye, self.target, [0.0, 1.0, 0.0])

    def projection(self) -> NDArray[np.float64]:
        """View-to-clip matrix (perspective)."""
        return perspective(self.fov_y_deg, self.aspect, NEAR, FAR)

    def view_proj(self) -> NDArray[np.float64]:
        return self.projection() @ self.view()

    def project(self, points: NDArray[np.float64], width: int, height: int) -> tuple[NDArray, NDArray]:
        """Pixel ``(col, row)`` (row 0 at the top) ``(P, 2)`` of render-frame ``points`` ``(P, 3)``
        and whether each is in front of the camera."""
        p = np.c_[points, np.ones(len(points))] @ self.view_proj().T
        w = p[:, 3]
        ndc = p[:, :2] / np.where(w > 0, w, 1.0)[:, None]
        col = (ndc[:, 0] + 1) / 2 * width
        row = (1 - (ndc[:, 1] + 1) / 2) * height
        return np.stack([col, row], axis=1), w > NEAR


def street_camera(start: NDArray[np.float64], end: NDArray[np.float64], aspect: float) -> Camera:
    """From :data:`EYE_HEIGHT` above ``start`` looking towards 1.2 m above the point a third of
    the way to ``end`` (render-frame ground points of the span's ends on the street's centre line)."""
    start, end = np.asarray(start, np.float64), np.asarray(end, np.float64)
    eye = start + [0.0, EYE_HEIGHT, 0.0]
    target = start + (end - start) / 3.0 + [0.0, 1.2, 0.0]
    return Camera(eye, target, float(aspect))
