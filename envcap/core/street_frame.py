"""A street's own frame: where its probes' cube axes point (issue 10: streets at any angle).

A street runs at ``yaw_deg`` in plan: the angle of its direction from world +X toward +Z
(``atan2(dz, dx)``, degrees).  Its frame keeps +Y up and turns X and Z by that angle: the
street runs along the frame's +X.  World -> frame, for directions (and for positions relative to
the frame's origin)::

    x_f =  cos(a) x + sin(a) z
    y_f =  y
    z_f = -sin(a) x + cos(a) z

A probe of that street is captured with its cube faces along the frame's axes (+X_f, -X_f, ...,
in OpenGL order): its texel for world direction ``d`` is the cube texel of ``R d``.  ``yaw_deg =
0`` is the world frame itself (streets along X; a street along Z may keep the world frame too).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


def plan_rotation(yaw_deg: float) -> NDArray[np.float64]:
    """(3, 3) float64 matrix ``R`` taking world vectors to the frame of a street at ``yaw_deg``
    (see the module docstring); orthonormal, det +1.  ``ValueError`` for a non-finite angle."""
    if not (isinstance(yaw_deg, (int, float, np.floating)) and math.isfinite(yaw_deg)):
        raise ValueError(f"street yaw must be a finite number of degrees, got {yaw_deg!r}")
    a = math.radians(float(yaw_deg))
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def to_frame(vectors: ArrayLike, yaw_deg: float) -> NDArray[np.float64]:
    """World vectors (..., 3) in the frame of a street at ``yaw_deg`` (float64)."""
    return np.asarray(vectors, np.float64) @ plan_rotation(yaw_deg).T


def from_frame(vectors: ArrayLike, yaw_deg: float) -> NDArray[np.float64]:
    """Frame vectors (..., 3) of a street at ``yaw_deg`` back in the world (float64)."""
    return np.asarray(vectors, np.float64) @ plan_rotation(yaw_deg)
