"""Flat-shaded triangle geometry from axis-aligned rectangles and boxes (numpy in, numpy out).

Every rectangle becomes 4 vertices and 2 triangles of its own (flat shading), wound
counter-clockwise seen from the side its unit normal points to (OpenGL's default front face).
All lengths are meters in the envcap world frame (+Y up).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.scene.model import SceneMesh

# For a rectangle normal to world axis k, the in-plane axes (i, j) with e_i x e_j = e_k.
_INPLANE: dict[int, tuple[int, int]] = {0: (1, 2), 1: (2, 0), 2: (0, 1)}


class MeshBuilder:
    """Accumulates axis-aligned rectangles (quads) and turns them into one :class:`SceneMesh`."""

    def __init__(self) -> None:
        self._corners: list[NDArray[np.float64]] = []  # (Q, 4, 3)
        self._normals: list[NDArray[np.float64]] = []  # (Q, 3)
        self._albedo: list[NDArray[np.float64]] = []  # (Q, 3)
        self._emission: list[NDArray[np.float64]] = []  # (Q, 3)

    def add_rects(
        self,
        axis: int,
        sign: int,
        plane: ArrayLike,
        lo: ArrayLike,
        hi: ArrayLike,
        albedo: ArrayLike,
        emission: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        """Add ``Q`` rectangles normal to world axis ``axis`` (0 = x, 1 = y, 2 = z).

        ``sign`` (+1 / -1) is the direction of the normal along ``axis``; ``plane`` (Q,) or scalar
        is the rectangle's coordinate on ``axis``; ``lo`` and ``hi`` (Q, 3) or (3,) are the
        rectangle's min / max corners (their ``axis`` component is ignored).  ``albedo`` and
        ``emission`` are (Q, 3) or (3,) linear RGB.  Rectangles with zero area are skipped.
        """
        if axis not in (0, 1, 2) or sign not in (1, -1):
            raise ValueError(f"bad rectangle axis {axis} / sign {sign}")
        lo = np.atleast_2d(np.asarray(lo, np.float64))
        hi = np.atleast_2d(np.asarray(hi, np.float64))
        plane = np.atleast_1d(np.asarray(plane, np.float64))
        q = max(lo.shape[0], hi.shape[0], plane.shape[0])
        lo, hi = _rows(lo, (q, 3)), _rows(hi, (q, 3))
        plane = _rows(plane, (q,))
        alb = _rows(np.asarray(albedo, np.float64), (q, 3))
        emi = _rows(np.asarray(emission, np.float64), (q, 3))
        i, j = _INPLANE[axis]
        keep = (hi[:, i] > lo[:, i]) & (hi[:, j] > lo[:, j])
        if not np.any(keep):
            return
        lo, hi, plane, alb, emi = lo[keep], hi[keep], plane[keep], alb[keep], emi[keep]
        q = lo.shape[0]
        c = np.empty((q, 4, 3))
        c[:, :, axis] = plane[:, None]
        # counter-clockwise seen from +axis: (i0,j0) (i1,j0) (i1,j1) (i0,j1)
        c[:, 0, i], c[:, 0, j] = lo[:, i], lo[:, j]
        c[:, 1, i], c[:, 1, j] = hi[:, i], lo[:, j]
        c[:, 2, i], c[:, 2, j] = hi[:, i], hi[:, j]
        c[:, 3, i], c[:, 3, j] = lo[:, i], hi[:, j]
        if sign < 0:
            c = c[:, ::-1]
        n = np.zeros((q, 3))
        n[:, axis] = sign
        self._corners.append(c)
        self._normals.append(n)
        self._albedo.append(np.array(alb))
        self._emission.append(np.array(emi))

    def add_boxes(
        self,
        lo: ArrayLike,
        hi: ArrayLike,
        albedo: ArrayLike,
        faces: tuple[str, ...] = ("+x", "-x", "+y", "+z", "-z"),
    ) -> None:
        """Add axis-aligned boxes ``lo`` .. ``hi`` ((B, 3) or (3,), meters) with outward normals.

        ``faces`` names the faces to emit (default: all but the bottom ``-y``, which stands on
        the ground and is never seen).  ``albedo`` is (B, 3) or (3,).
        """
        lo = np.atleast_2d(np.asarray(lo, np.float64))
        hi = np.atleast_2d(np.asarray(hi, np.float64))
        if np.any(hi <= lo):
            raise ValueError("box with zero or negative size")
        for f in faces:
            sign = 1 if f[0] == "+" else -1
            axis = "xyz".index(f[1])
            plane = hi[:, axis] if sign > 0 else lo[:, axis]
            self.add_rects(axis, sign, plane, lo, hi, albedo)

    def build(self) -> SceneMesh:
        """The accumulated quads as a flat-shaded :class:`SceneMesh` (float32, uint32 indices;
        positions relative to their :func:`~envcap.scene.model.local_origin`)."""
        if not self._corners:
            return SceneMesh.concatenate([])
        c = np.concatenate(self._corners)
        q = c.shape[0]
        pos = c.reshape(-1, 3)
        nrm = np.repeat(np.concatenate(self._normals), 4, axis=0)
        alb = np.repeat(np.concatenate(self._albedo), 4, axis=0)
        emi = np.repeat(np.concatenate(self._emission), 4, axis=0)
        base = (np.arange(q, dtype=np.uint32) * 4)[:, None]
        idx = np.concatenate([base + np.array([0, 1, 2], np.uint32), base + np.array([0, 2, 3], np.uint32)], axis=1)
        return SceneMesh.from_world(pos, nrm, alb, emi, idx.reshape(-1, 3))


def _rows(a: NDArray[np.float64], shape: tuple[int, ...]) -> NDArray[np.float64]:
    """``a`` broadcast to ``shape`` (a view; ``a`` itself when it has that shape already: the
    one-rectangle calls of a building row skip numpy's broadcasting machinery)."""
    if a.shape == shape:
        return a
    if a.ndim == 1 and len(shape) == 2 and shape[0] == 1 and a.shape[0] == shape[1]:
        return a.reshape(shape)  # one row: (3,) -> (1, 3)
    return np.broadcast_to(a, shape)


def subtract_interval(pieces: list[tuple[float, float]], lo: float, hi: float) -> list[tuple[float, float]]:
    """Remove the open interval (``lo``, ``hi``) from a list of disjoint intervals."""
    out: list[tuple[float, float]] = []
    for a, b in pieces:
        if hi <= a or lo >= b:
            out.append((a, b))
            continue
        if lo > a:
            out.append((a, lo))
        if hi < b:
            out.append((hi, b))
    return out

