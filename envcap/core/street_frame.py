"""A street's own frame: where its probes' cube axes point (issue 10: streets at any angle).

A street runs at ``yaw_deg`` in plan: the angle of its direction from world +X toward +Z
(``atan2(dz, dx)``, degrees).  Its frame keeps +Y up and turns X and Z by that angle: the
street runs along the frame's +X.  World -> frame, for directions (and for positions relative to
the frame's origin)::

    x_f =  cos(a) x + sin(a) z
    y_f =  y
    z_f = -sin(a) x + cos(a) z

Positions: :func:`world_to_frame` / :func:`frame_to_world` also move the origin to the
street's plan point ``origin_xz`` (x, z), so ``p_f = R (p - (ox, 0, oz))``.

A probe of that street is captured with its cube faces along the frame's axes (+X_f, -X_f, ...,
in OpenGL order): its texel for world direction ``d`` is the cube texel of ``R d``.  ``yaw_deg =
0`` is the world frame itself (streets along X; a street along Z may keep the world frame too).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


_QUARTER_TURNS = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
"""(cos, sin) at 0, 90, 180 and 270 degrees, exactly."""


def yaw_cos_sin(yaw_deg: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(cos, sin)`` of ``yaw_deg`` degrees (any shape, float64), exact at every multiple of 90
    degrees: 0 and +-1 there, not the 6e-17 of ``cos(radians(90))``, so that a direction exactly
    along a street turned by 90, 180 or 270 degrees stays exactly parallel to its facades (as in
    the same street without a frame).  Elsewhere ``cos``/``sin`` of the angle reduced into
    (-360, 360) by ``fmod`` (exact, sign kept: small angles keep their precision).  Non-finite
    angles give NaN (callers check first)."""
    a = np.asarray(yaw_deg, np.float64)
    with np.errstate(invalid="ignore"):
        r = np.fmod(a, 360.0)                            # exact for finite a; NaN for +-inf, NaN
        quarter = np.fmod(r, 90.0) == 0.0
        k = np.where(quarter, r // 90.0, 0).astype(np.int64) % 4
    t = np.radians(r)
    c = np.where(quarter, _QUARTER_TURNS[k, 0], np.cos(t))
    s = np.where(quarter, _QUARTER_TURNS[k, 1], np.sin(t))
    return c, s


def plan_rotation(yaw_deg: float) -> NDArray[np.float64]:
    """(3, 3) float64 matrix ``R`` taking world vectors to the frame of a street at ``yaw_deg``
    (see the module docstring); orthonormal, det +1, exact at multiples of 90 degrees
    (:func:`yaw_cos_sin`).  ``ValueError`` for a non-finite angle."""
    if not (isinstance(yaw_deg, (int, float, np.floating)) and math.isfinite(yaw_deg)):
        raise ValueError(f"street yaw must be a finite number of degrees, got {yaw_deg!r}")
    cs = yaw_cos_sin(float(yaw_deg))
    c, s = float(cs[0]), float(cs[1])
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def to_frame(vectors: ArrayLike, yaw_deg: float) -> NDArray[np.float64]:
    """World vectors (..., 3) in the frame of a street at ``yaw_deg`` (float64)."""
    return np.asarray(vectors, np.float64) @ plan_rotation(yaw_deg).T


def from_frame(vectors: ArrayLike, yaw_deg: float) -> NDArray[np.float64]:
    """Frame vectors (..., 3) of a street at ``yaw_deg`` back in the world (float64)."""
    return np.asarray(vectors, np.float64) @ plan_rotation(yaw_deg)


def _origin3(origin_xz: ArrayLike) -> NDArray[np.float64]:
    o = np.asarray(origin_xz, np.float64)
    if o.shape != (2,) or not np.all(np.isfinite(o)):
        raise ValueError(f"street frame origin must be 2 finite numbers (x, z), got {origin_xz!r}")
    return np.array([o[0], 0.0, o[1]])


def world_to_frame(points: ArrayLike, yaw_deg: float, origin_xz: ArrayLike = (0.0, 0.0)) -> NDArray[np.float64]:
    """World points (..., 3) (m) in the frame of a street at ``yaw_deg`` whose frame origin is
    the world plan point ``origin_xz`` = (x, z): ``R (p - (ox, 0, oz))``, float64.  Heights (y)
    are unchanged.  ``yaw_deg = 0`` and origin (0, 0) return the points unchanged (exactly)."""
    p = np.asarray(points, np.float64)
    r, o = plan_rotation(yaw_deg), _origin3(origin_xz)
    if float(yaw_deg) == 0.0 and not np.any(o):
        return p.copy()
    return (p - o) @ r.T


def frame_to_world(points: ArrayLike, yaw_deg: float, origin_xz: ArrayLike = (0.0, 0.0)) -> NDArray[np.float64]:
    """Frame points (..., 3) (m) of a street at ``yaw_deg`` with frame origin ``origin_xz`` back in
    the world: ``R^T f + (ox, 0, oz)``, float64 (the inverse of :func:`world_to_frame`)."""
    f = np.asarray(points, np.float64)
    r, o = plan_rotation(yaw_deg), _origin3(origin_xz)
    if float(yaw_deg) == 0.0 and not np.any(o):
        return f.copy()
    return f @ r + o


class OptionalFrame:
    """Mixin for records whose street frame is optional (``yaw_deg`` and ``origin_xz`` fields that
    may be ``None``, as in the manifest and the city index, which omit them for world-frame
    streets): the frame as numbers, and whether there is one."""

    yaw_deg: float | None
    origin_xz: tuple[float, float] | None

    @property
    def frame_yaw_deg(self) -> float:
        """``yaw_deg`` as a number (0.0 when ``None``: the world frame)."""
        return 0.0 if self.yaw_deg is None else float(self.yaw_deg)

    @property
    def frame_origin_xz(self) -> tuple[float, float]:
        """``origin_xz`` as numbers ((0.0, 0.0) when ``None``)."""
        return (0.0, 0.0) if self.origin_xz is None else (float(self.origin_xz[0]), float(self.origin_xz[1]))

    @property
    def framed(self) -> bool:
        """True when the street has its own frame (a yaw or origin other than 0)."""
        return self.frame_yaw_deg != 0.0 or self.frame_origin_xz != (0.0, 0.0)
