"""Projection matrices of the capture: the six cube-face frusta and the sun's orthographic frustum.

All matrices are row-major numpy float64 (``clip = M @ (x, 1)``); GLSL ``mat4`` uniforms take
their transpose (column-major, see :mod:`envcap.gpu.uniforms`).

Cube faces follow :mod:`envcap.core.cube`: :data:`FACE_ROWS` ``[f]`` is the 3 x 3 matrix ``R_f``
with ``(sc, tc, ma) = R_f @ d``; a direction ``d`` has face coordinates ``u = sc / ma``,
``v = tc / ma`` (:func:`envcap.core.cube.direction_to_face_uv`) and ``ma > 0`` in front.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FACE_ROWS: NDArray[np.float64] = np.array(
    [
        [[0, 0, -1], [0, -1, 0], [1, 0, 0]],    # +X: sc = -z, tc = -y, ma =  x
        [[0, 0, 1], [0, -1, 0], [-1, 0, 0]],    # -X: sc =  z, tc = -y, ma = -x
        [[1, 0, 0], [0, 0, 1], [0, 1, 0]],      # +Y: sc =  x, tc =  z, ma =  y
        [[1, 0, 0], [0, 0, -1], [0, -1, 0]],    # -Y: sc =  x, tc = -z, ma = -y
        [[1, 0, 0], [0, -1, 0], [0, 0, 1]],     # +Z: sc =  x, tc = -y, ma =  z
        [[-1, 0, 0], [0, -1, 0], [0, 0, -1]],   # -Z: sc = -x, tc = -y, ma = -z
    ],
    dtype=np.float64,
)
"""(6, 3, 3): rows ``sc``, ``tc``, ``ma`` of each cube face (GL face order)."""


def face_clip_matrix(face: int, near: float = 0.05, far: float = math.inf) -> NDArray[np.float64]:
    """4x4 matrix mapping ``(x - probe, 1)`` to GL clip space for cube face ``face``.

    NDC ``x = u = 2s - 1`` and ``y = v = 2t - 1`` (framebuffer row 0 = t near 0, so a readback
    needs no flip), ``w`` = distance along the face's major axis; depth maps ``near`` to -1 and
    ``far`` (``inf`` allowed: infinite projection) to +1.  Row-major (``M @ x``).
    """
    if not (0 < near < far):
        raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
    r = FACE_ROWS[face]
    m = np.zeros((4, 4))
    m[0, :3] = r[0]
    m[1, :3] = r[1]
    m[3, :3] = r[2]
    if math.isinf(far):
        a, b = 1.0, -2.0 * near
    else:
        a, b = (far + near) / (far - near), -2.0 * far * near / (far - near)
    m[2, :3] = a * r[2]
    m[2, 3] = b
    return m


def face_clip_matrix_reversed(face: int, near: float = 0.05, far: float = math.inf) -> NDArray[np.float64]:
    """Like :func:`face_clip_matrix` but with reversed depth for ``glClipControl(.., ZERO_TO_ONE)``.

    ``x``, ``y``, ``w`` rows are those of :func:`face_clip_matrix`; NDC depth ``z / w`` is 1 at
    ``ma = near`` and 0 at ``ma = far`` (``inf``: ``z / w = near / ma``).  Stored in a float32
    depth buffer (:mod:`envcap.gpu.float_depth`) this keeps a relative precision of about 2^-24
    in distance at every range (a 24-bit buffer with the standard mapping resolves only ~10 cm
    at 300 m).  Row-major.
    """
    if not (0 < near < far):
        raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
    m = face_clip_matrix(face, near, far)
    r = FACE_ROWS[face]
    if math.isinf(far):
        a, b = 0.0, near
    else:
        a, b = -near / (far - near), near * far / (far - near)
    m[2, :3] = a * r[2]
    m[2, 3] = b
    return m


def _light_basis(l: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows: right, up, back (= l) of an orthonormal light frame looking along -l."""
    helper = np.array([0.0, 1.0, 0.0]) if abs(l[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(helper, l)
    right /= np.linalg.norm(right)
    up = np.cross(l, right)
    return np.stack([right, up, l])


def light_clip_matrix(sun_dir: NDArray[np.floating], lo: NDArray[np.floating], hi: NDArray[np.floating],
                      margin: float = 1.0, occluders: NDArray[np.floating] | None = None
                      ) -> tuple[NDArray[np.float64], float, float]:
    """Orthographic light clip matrix fitted to the box ``[lo, hi]`` seen from the sun (points in
    the frame of ``lo``, ``hi``: the capture uses the mesh origin's).

    ``sun_dir`` (3,) points toward the sun (any length > 0); ``lo``, ``hi`` (3,) meters.
    Returns ``(matrix, extent_xy, depth_range)``: the larger side (m) of the square light-space
    window and the depth range (m) that maps to [-1, 1] (nearest the sun -> -1).  ``margin``
    meters pad every side so that flat boxes still have a non-zero depth range.  ``occluders``
    (K, 3): points (e.g. the whole mesh's box corners) whose depth toward the sun the map must
    also reach, so that geometry outside the box still casts its shadow into it.
    """
    l = np.asarray(sun_dir, dtype=np.float64)
    l = l / np.linalg.norm(l)
    basis = _light_basis(l)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    e = corners @ basis.T
    emin, emax = e.min(axis=0) - margin, e.max(axis=0) + margin
    if occluders is not None and len(occluders):
        emax[2] = max(emax[2], float((np.asarray(occluders, np.float64) @ basis[2]).max()) + margin)
    center = 0.5 * (emin + emax)
    half = 0.5 * max(emax[0] - emin[0], emax[1] - emin[1])
    depth = emax[2] - emin[2]
    m = np.zeros((4, 4))
    m[0, :3] = basis[0] / half
    m[0, 3] = -center[0] / half
    m[1, :3] = basis[1] / half
    m[1, 3] = -center[1] / half
    # z_ndc = -1 at the sun-most point (l . p = emax_z), +1 at the far side.
    m[2, :3] = -2.0 * basis[2] / depth
    m[2, 3] = 2.0 * emax[2] / depth - 1.0
    m[3, 3] = 1.0
    return m, 2.0 * half, depth
