"""Cube-map conventions: the one source of truth for envcap.

Conventions (tested against OpenGL itself in ``tests/gpu/test_cube_gl.py``):

* World frame: right-handed, meters, +Y up.
* Faces in OpenGL order: 0 = +X, 1 = -X, 2 = +Y, 3 = -Y, 4 = +Z, 5 = -Z.
* A cube is a numpy array of shape ``(6, N, N, C)`` indexed ``[face, row, column, channel]``
  with ``row = t`` and ``column = s`` as in the OpenGL specification (table 8.19, "Selection of
  cube map images"). Uploading ``cube[f]`` as-is (row 0 first) to
  ``GL_TEXTURE_CUBE_MAP_POSITIVE_X + f`` samples correctly with ``texture(samplerCube, dir)``.
* Texel ``(row j, column i)`` of an ``N``-texel face has its center at
  ``s = (i + 0.5) / N``, ``t = (j + 0.5) / N``.  With ``u = 2s - 1`` and ``v = 2t - 1`` the
  (unnormalized) direction of a face point is::

      +X: ( 1, -v, -u)     -X: (-1, -v,  u)
      +Y: ( u,  1,  v)     -Y: ( u, -1, -v)
      +Z: ( u, -v,  1)     -Z: (-u, -v, -1)

OpenEXR's cube env maps use another per-face orientation; ``envcap.formats.exr_cube`` converts at the
file boundary only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.core.checks import finite_directions, positive_int

FACE_NAMES: tuple[str, ...] = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
"""Face names in OpenGL order (index = face number)."""

FloatArray = NDArray[np.floating]


def texel_centers(n: int) -> NDArray[np.float64]:
    """Face coordinates ``u = 2s - 1`` of the ``n`` texel centers along one axis, in (-1, 1)."""
    n = positive_int(n, "cube face size")
    return (np.arange(n, dtype=np.float64) + 0.5) / n * 2.0 - 1.0


def face_uv_to_direction(face: int | NDArray[np.integer], u: FloatArray, v: FloatArray) -> NDArray[np.float64]:
    """Unnormalized direction of face coordinates ``u = 2s - 1``, ``v = 2t - 1`` on ``face``.

    ``face`` is a face index (0..5) or an integer array broadcastable with ``u`` and ``v``.
    Returns an array of shape ``broadcast(face, u, v).shape + (3,)``, float64, whose major axis
    component is exactly +-1.
    """
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    face = np.asarray(face)
    if np.any((face < 0) | (face > 5)):
        raise ValueError("face index must be in 0..5")
    face, u, v = np.broadcast_arrays(face, u, v)
    one = np.ones_like(u)
    table = [
        (one, -v, -u),
        (-one, -v, u),
        (u, one, v),
        (u, -one, -v),
        (u, -v, one),
        (-u, -v, -one),
    ]
    out = np.empty(u.shape + (3,), dtype=np.float64)
    for f, (x, y, z) in enumerate(table):
        m = face == f
        out[..., 0][m] = x[m]
        out[..., 1][m] = y[m]
        out[..., 2][m] = z[m]
    return out


def texel_directions(n: int, dtype: type = np.float64) -> NDArray[np.floating]:
    """Unit directions of every texel center, shape ``(6, n, n, 3)`` indexed ``[face, t, s]``."""
    c = texel_centers(n)
    v, u = np.meshgrid(c, c, indexing="ij")  # v varies along rows (t), u along columns (s)
    faces = np.arange(6)[:, None, None]
    d = face_uv_to_direction(faces, u[None], v[None])
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return d.astype(dtype, copy=False)


def _area_element(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    # Solid angle of the face rectangle [0, x] x [0, y] on the plane at distance 1, signed.
    return np.arctan2(x * y, np.sqrt(x * x + y * y + 1.0))


def texel_solid_angle(row: NDArray[np.integer], col: NDArray[np.integer], n: int) -> NDArray[np.float64]:
    """Exact solid angle (sr) of texels ``(row, col)`` of an ``n``-texel face (any face: they are
    all alike), for selected texels only, so that a large ``n`` costs no ``(6, n, n)`` array."""
    n = positive_int(n, "cube face size")
    col = np.asarray(col, dtype=np.float64)
    row = np.asarray(row, dtype=np.float64)
    x0, x1 = col / n * 2.0 - 1.0, (col + 1) / n * 2.0 - 1.0
    y0, y1 = row / n * 2.0 - 1.0, (row + 1) / n * 2.0 - 1.0
    return _area_element(x1, y1) - _area_element(x0, y1) - _area_element(x1, y0) + _area_element(x0, y0)


def texel_solid_angles(n: int) -> NDArray[np.float64]:
    """Exact solid angle of every texel in steradians, shape ``(6, n, n)``; they sum to 4*pi.

    Computed in float64 from the closed form of the solid angle subtended by an axis-aligned
    rectangle on the plane at unit distance (no small-texel approximation).
    """
    n = positive_int(n, "cube face size")
    row, col = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    return np.broadcast_to(texel_solid_angle(row, col, n), (6, n, n)).copy()


def direction_to_face_uv(d: FloatArray) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Face index and face coordinates ``(u, v)`` in [-1, 1] of directions ``d`` (shape ``(..., 3)``).

    The major axis is the component of largest magnitude; ties go to X before Y before Z, as in
    Mesa.  The sign of a zero component does not matter.  A zero or non-finite direction is
    invalid and raises ``ValueError``: a silent face choice for it would be a wrong answer.
    """
    d = finite_directions(d)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    ma = np.maximum(ax, np.maximum(ay, az))
    xmaj = (ax >= ay) & (ax >= az)
    ymaj = ~xmaj & (ay >= az)
    face = np.where(xmaj, np.where(x >= 0, 0, 1), np.where(ymaj, np.where(y >= 0, 2, 3), np.where(z >= 0, 4, 5)))
    sc = np.select([face == 0, face == 1, face == 2, face == 3, face == 4], [-z, z, x, x, x], -x)
    tc = np.select([face == 0, face == 1, face == 2, face == 3, face == 4], [-y, -y, z, -z, -y], -y)
    return face.astype(np.int64), sc / ma, tc / ma


def direction_to_face_st(d: FloatArray) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Face index and texture coordinates ``(s, t)`` in [0, 1] of directions ``d`` (``(..., 3)``)."""
    face, u, v = direction_to_face_uv(d)
    return face, (u + 1.0) * 0.5, (v + 1.0) * 0.5


def direction_to_texel(d: FloatArray, n: int) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Face, row (t) and column (s) of the texel of an ``n``-texel cube that contains ``d``."""
    n = positive_int(n, "cube face size")
    face, s, t = direction_to_face_st(d)
    col = np.clip(np.floor(s * n), 0, n - 1).astype(np.int64)
    row = np.clip(np.floor(t * n), 0, n - 1).astype(np.int64)
    return face, row, col


def check_cube(cube: NDArray, name: str = "cube") -> NDArray:
    """Validate a cube array of shape ``(6, N, N, C)`` and return it; raises ``ValueError``."""
    a = np.asarray(cube)
    if a.ndim != 4 or a.shape[0] != 6 or a.shape[1] != a.shape[2] or a.shape[1] < 1:
        raise ValueError(f"{name} must have shape (6, N, N, C), got {a.shape}")
    return a


def horizontal_cross(cube: NDArray, inside: bool = True, fill: float = 0.0) -> NDArray:
    """Unfold a cube ``(6, N, N, C)`` into a horizontal cross of shape ``(3N, 4N, C)``.

    With ``inside=False`` the faces are laid out as stored (``-X +Z +X -Z`` in the middle row,
    ``+Y`` above and ``-Y`` below ``+Z``): every shared edge is continuous, and the picture is the
    cube seen from outside.  With ``inside=True`` (default) the whole cross is mirrored left to
    right, which is the view from the probe's center (as in a panorama: turning right moves to
    the right in the picture).  Empty cells get ``fill``.
    """
    a = check_cube(cube)
    n = a.shape[1]
    out = np.full((3 * n, 4 * n) + a.shape[3:], fill, dtype=a.dtype)
    place = {1: (1, 0), 4: (1, 1), 0: (1, 2), 5: (1, 3), 2: (0, 1), 3: (2, 1)}
    for f, (r, c) in place.items():
        out[r * n:(r + 1) * n, c * n:(c + 1) * n] = a[f]
    if inside:
        out = out[:, ::-1].copy()
    return out
