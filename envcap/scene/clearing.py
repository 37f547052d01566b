"""Keeping roadways clear: the ground rectangles of roadways and placed buildings, and the pieces
of a new building's footprint that stay out of them (``docs/scenes.md``, "Roadways stay clear").

Rectangles are world ``[x0, x1] x [z0, z1]`` (m) on the ground.  A footprint is cut, along its
own street, by every rectangle that overlaps it (by more than :data:`CROSS_EPS_M` across the
street); the pieces narrower than :data:`~envcap.scene.limits.MIN_PIECE_M` are dropped.  Finding
the overlapping rectangles is one vectorized pass over those placed so far, so a row of ``n``
buildings costs O(n^2) comparisons in numpy, not in Python.  The roadway of a street at an angle
is its turned rectangle (``GroundRects.turned``, world corners): it cuts the along-street span
where the footprint's cross strip meets it (:func:`turned_span`), not its world box.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.scene.geometry import subtract_interval
from envcap.scene.limits import MIN_PIECE_M
from envcap.scene.model import Street

CROSS_EPS_M = 1e-6
"""Rectangles that overlap a footprint by at most this across its street do not cut it (m)."""


class GroundRects:
    """Rectangles on the ground in the order they were added, ``(n, 4)`` float64 rows
    ``(x0, x1, z0, z1)``; grows by doubling."""

    def __init__(self) -> None:
        self._rows: NDArray[np.float64] = np.empty((64, 4))
        self._n = 0
        self.turned: list[NDArray[np.float64]] = []
        """Turned rectangles (roadways of streets at an angle): (4, 2) world corners (x, z), in order around."""

    def add(self, x0: float, x1: float, z0: float, z1: float) -> None:
        if self._n == self._rows.shape[0]:
            self._rows = np.concatenate([self._rows, np.empty_like(self._rows)])
        self._rows[self._n] = (x0, x1, z0, z1)
        self._n += 1

    def add_along(self, along_axis: int, a0: float, a1: float, c0: float, c1: float) -> None:
        """Add the rectangle along-axis ``[a0, a1]``, cross-axis ``[c0, c1]`` (``along_axis`` 0 = x, 2 = z)."""
        if along_axis == 0:
            self.add(a0, a1, c0, c1)
        else:
            self.add(c0, c1, a0, a1)

    def cutting(self, along_axis: int, a0: float, a1: float, c0: float, c1: float) -> NDArray[np.float64]:
        """The rectangles that overlap the footprint along ``[a0, a1]`` and across ``(c0, c1)``
        (by more than :data:`CROSS_EPS_M`), in the order added, as rows ``(ra0, ra1, rc0, rc1)``
        in the footprint's own axes."""
        r = self._rows[: self._n]
        along, cross = (r[:, 0:2], r[:, 2:4]) if along_axis == 0 else (r[:, 2:4], r[:, 0:2])
        keep = ((cross[:, 1] > c0 + CROSS_EPS_M) & (cross[:, 0] < c1 - CROSS_EPS_M)
                & (along[:, 1] > a0) & (along[:, 0] < a1))
        return np.concatenate([along[keep], cross[keep]], axis=1)


def roadways(streets: list[Street]) -> GroundRects:
    """The roadway of every street: between its facade planes over ``[start, end]``."""
    rects = GroundRects()
    for st in streets:
        if st.framed:  # a street at an angle: its turned roadway
            rects.turned.append(st.plan_corners())
            continue
        rects.add_along(st.along_index, st.start, st.end, st.facade_min, st.facade_max)
    return rects


def clear_pieces(rects: GroundRects, along_axis: int, a0: float, a1: float, c0: float,
                 c1: float) -> list[tuple[float, float]]:
    """Along-street pieces of the footprint (along ``[a0, a1]``, across ``[c0, c1]``) that stay out
    of every rectangle of ``rects``, at least :data:`~envcap.scene.limits.MIN_PIECE_M` long."""
    pieces = [(a0, a1)]
    for ra0, ra1, _, _ in rects.cutting(along_axis, a0, a1, c0, c1).tolist():
        pieces = subtract_interval(pieces, ra0, ra1)
    for corners in rects.turned:
        span = turned_span(corners, along_axis, c0, c1)
        if span is not None and span[1] > a0 and span[0] < a1:
            pieces = subtract_interval(pieces, *span)
    return [(x0, x1) for x0, x1 in pieces if x1 - x0 >= MIN_PIECE_M]


def turned_span(corners: NDArray[np.float64], along_axis: int, c0: float, c1: float) -> tuple[float, float] | None:
    """``(lo, hi)``: the along-axis span (m) of the convex polygon ``corners`` (K, 2) world (x, z)
    within the cross strip ``(c0, c1)`` (narrowed by :data:`CROSS_EPS_M`), or ``None`` when the
    polygon misses the strip (``along_axis`` 0 = x, 2 = z)."""
    poly = np.asarray(corners, np.float64)[:, [0, 1] if along_axis == 0 else [1, 0]]   # (along, cross)
    for bound, side in ((c0 + CROSS_EPS_M, 1.0), (c1 - CROSS_EPS_M, -1.0)):   # keep side * (cross - bound) >= 0
        f = side * (poly[:, 1] - bound)
        out = []
        for i in range(len(poly)):   # Sutherland-Hodgman against one half-plane
            j = (i + 1) % len(poly)
            if f[i] >= 0:
                out.append(poly[i])
            if (f[i] >= 0) != (f[j] >= 0):
                out.append(poly[i] + (f[i] / (f[i] - f[j])) * (poly[j] - poly[i]))
        if not out:
            return None
        poly = np.array(out)
    return float(poly[:, 0].min()), float(poly[:, 0].max())
