"""Numpy arithmetic in GLSL evaluation order, so that the float32 twins round like the GPU."""

from __future__ import annotations

from numpy.typing import NDArray


def dot3(a: NDArray, b: NDArray) -> NDArray:
    """``dot(a, b)`` of ``(..., 3)`` vectors in the GLSL order ``(a.x*b.x + a.y*b.y) + a.z*b.z``."""
    return (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]) + a[..., 2] * b[..., 2]
