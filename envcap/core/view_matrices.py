"""OpenGL camera matrices, float64 ``(4, 4)`` for column vectors (``clip = P @ V @ p``): a look-at
view (right-handed, the view looking down -Z), a perspective and an orthographic projection with
``z`` in [-1, 1] (the matrices of ``gluLookAt``, ``gluPerspective`` and ``glOrtho``).  Used by the
scene preview and the crowd's camera."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def look_at(eye: ArrayLike, target: ArrayLike, up: ArrayLike) -> NDArray[np.float64]:
    """World-to-view matrix of a camera at ``eye`` looking at ``target`` (m), ``up`` roughly up
    (not parallel to ``target - eye``)."""
    eye = np.asarray(eye, np.float64)
    f = np.asarray(target, np.float64) - eye
    f /= np.linalg.norm(f)
    s = np.cross(f, np.asarray(up, np.float64))
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fovy_deg: float, aspect: float, near: float, far: float) -> NDArray[np.float64]:
    """View-to-clip matrix: vertical field of view ``fovy_deg`` (degrees), ``aspect`` width /
    height, clip planes ``near`` < ``far`` (m)."""
    f = 1.0 / np.tan(np.deg2rad(fovy_deg) / 2)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = f / aspect, f
    m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
    m[3, 2] = -1
    return m


def ortho(l: float, r: float, b: float, t: float, n: float, f: float) -> NDArray[np.float64]:
    """View-to-clip matrix of the box ``[l, r] x [b, t] x [-f, -n]`` (view space, m)."""
    m = np.eye(4)
    m[0, 0], m[1, 1], m[2, 2] = 2 / (r - l), 2 / (t - b), -2 / (f - n)
    m[:3, 3] = -(r + l) / (r - l), -(t + b) / (t - b), -(f + n) / (f - n)
    return m
