"""The two placement rules of docs/placement.md, on one street: plain numpy, no captures.

* :func:`best_subset`: the exact minimum, over every choice of ``count`` of ``K`` candidate
  positions, of the mean error of points served by their nearest probe along the street (the
  runtime's choice: ``envcap.runtime.parallax.nearest_probe``, ties to the lower index), given the
  error ``E[k, j]`` of candidate ``k`` serving point ``j``.  The nearest probe cuts the street into
  intervals at the midpoints between consecutive probes, so the total is a sum of terms of
  consecutive pairs: a dynamic programme over (probes placed, last probe) finds the optimum in
  ``O(count K^2)``.
* :func:`density_positions`: ``count`` positions at the quantiles ``(i + 1/2) / count`` of a
  piecewise-constant probe density (a uniform density gives the uniform placement exactly).

Conventions: along-street coordinates in m (the street's frame), candidate coordinates ``s``
strictly increasing; errors are any non-negative numbers (``inf``: this candidate cannot serve
that point), one row per candidate, one column per point.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def served_error(chosen: ArrayLike, s: ArrayLike, points: ArrayLike, errors: ArrayLike) -> float:
    """Mean over points of ``errors[k, j]`` where ``k`` is the candidate among ``chosen``
    (indices into ``s``, ascending) nearest to point ``j`` along the street (ties: lower index)."""
    idx = np.asarray(chosen, np.int64)
    s, x, e = np.asarray(s, np.float64), np.asarray(points, np.float64), np.asarray(errors, np.float64)
    nearest = np.argmin(np.abs(x[:, None] - s[idx][None, :]), axis=1)
    return float(np.mean(e[idx[nearest], np.arange(x.size)]))


def best_subset(s: ArrayLike, points: ArrayLike, errors: ArrayLike, count: int) -> tuple[NDArray[np.int64], float]:
    """The ``count`` candidates (indices into ``s``, ascending) whose nearest-probe service of
    ``points`` has the least mean error (:func:`served_error`), and that mean.

    ``s`` ``(K,)`` candidate coordinates (strictly increasing), ``points`` ``(J,)`` coordinates of
    the points (J >= 1), ``errors`` ``(K, J)``.  Exact (dynamic programme over the intervals
    between consecutive probes, module docstring); ties between equal totals go to the choice
    found first (deterministic).  ``ValueError`` unless ``1 <= count <= K``.
    """
    s = np.asarray(s, np.float64)
    x = np.asarray(points, np.float64)
    e = np.asarray(errors, np.float64)
    k_count, j_count = s.size, x.size
    if not 1 <= count <= k_count:
        raise ValueError(f"best_subset: need 1 <= count <= {k_count} candidates, got {count}")
    if e.shape != (k_count, j_count) or j_count < 1:
        raise ValueError(f"best_subset: errors must be (K, J) = ({k_count}, {j_count}) with J >= 1, got {e.shape}")
    if np.any(np.diff(s) <= 0):
        raise ValueError("best_subset: candidate coordinates must be strictly increasing")
    order = np.argsort(x, kind="stable")
    xs = x[order]
    ordered = e[:, order]
    finite = np.isfinite(ordered)
    if np.any(ordered[finite] < 0) or np.any(np.isnan(ordered)):
        raise ValueError("best_subset: errors must be >= 0 (or inf)")
    # a point a candidate cannot serve costs more than all finite errors together: the programme
    # serves as many points as it can, then minimises the error (and the mean says inf)
    big = 1e6 * (1.0 + float(ordered[finite].sum()))
    fin = np.concatenate([np.zeros((k_count, 1)), np.cumsum(np.where(finite, ordered, 0.0), axis=1)], axis=1)
    cnt = np.concatenate([np.zeros((k_count, 1)), np.cumsum(~finite, axis=1)], axis=1)

    def span(k: NDArray, i0: NDArray, i1: NDArray) -> NDArray[np.float64]:
        """Cost of candidate(s) ``k`` serving the sorted points ``i0 .. i1 - 1`` (exact when it can serve all)."""
        return (fin[k, i1] - fin[k, i0]) + big * (cnt[k, i1] - cnt[k, i0])

    upto = np.searchsorted(xs, s, side="right")                      # points at or left of each candidate
    rows = np.arange(k_count)
    head = span(rows, np.zeros_like(upto), upto)                     # points left of the first probe
    tail = span(rows, upto, np.full_like(upto, j_count))             # points right of the last probe
    a, b = rows[:, None], rows[None, :]
    mid = np.searchsorted(xs, 0.5 * (s[:, None] + s[None, :]), side="right")   # points <= the midpoint of a, b
    mid = np.clip(mid, upto[:, None], upto[None, :])                 # (for a < b; the rest is masked)
    seg = span(a, np.broadcast_to(upto[:, None], mid.shape), mid) + span(b, mid, np.broadcast_to(upto[None, :], mid.shape))
    seg = np.where(a < b, seg, np.inf)
    best = head.copy()
    back = []
    for _ in range(count - 1):
        total = best[:, None] + seg                                  # previous probe a, next probe b
        arg = np.argmin(total, axis=0)
        best = total[arg, rows]
        back.append(arg)
    last = int(np.argmin(best + tail))
    total = float((best + tail)[last])
    total = np.inf if total >= big else total
    chosen = [last]
    for arg in reversed(back):
        chosen.append(int(arg[chosen[-1]]))
    return np.array(chosen[::-1], np.int64), total / j_count


def density_positions(edges: ArrayLike, density: ArrayLike, count: int) -> NDArray[np.float64]:
    """``count`` positions (m, ascending) at the quantiles ``(i + 1/2) / count`` of the
    piecewise-constant density ``density[c]`` (>= 0, not all 0) on the cells ``[edges[c],
    edges[c + 1]]``: the inverse of its cumulative, linear within a cell.  A constant density
    over ``[a, b]`` gives ``a + (i + 1/2) (b - a) / count``, the uniform placement."""
    edges = np.asarray(edges, np.float64)
    rho = np.asarray(density, np.float64)
    if edges.ndim != 1 or rho.shape != (edges.size - 1,) or rho.size < 1 or np.any(np.diff(edges) <= 0):
        raise ValueError("density_positions: need ascending edges (C + 1,) and a density (C,)")
    if not (np.all(np.isfinite(rho)) and np.all(rho >= 0) and rho.sum() > 0):
        raise ValueError("density_positions: the density must be finite, >= 0 and not all 0")
    if count < 1:
        raise ValueError(f"density_positions: count must be >= 1, got {count}")
    mass = rho * np.diff(edges)
    cum = np.concatenate([[0.0], np.cumsum(mass)])
    q = (np.arange(count) + 0.5) / count * cum[-1]
    cell = np.clip(np.searchsorted(cum, q, side="right") - 1, 0, rho.size - 1)
    while np.any(mass[cell] == 0):               # a quantile on the edge of an empty cell: the next cell holding mass
        cell = np.where(mass[cell] == 0, np.minimum(cell + 1, rho.size - 1), cell)
    frac = (q - cum[cell]) / mass[cell]
    return edges[cell] + np.clip(frac, 0.0, 1.0) * np.diff(edges)[cell]
