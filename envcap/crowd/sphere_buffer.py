"""The spheres each walker's fragments are shadowed by, per frame: its own blocker bones (placed in
the vertex shader) and its neighbours, near ones by their bone spheres, far ones by one sphere
(the crowd LOD of :mod:`envcap.dynamic.crowd_lod`).

Per walker ``i``, the host lists its :data:`NEIGHBOURS` nearest other walkers (distance between
one-sphere centres, nearest first; ties by index).  The fragment shader
(``shaders/crowd/crowd_frag.glsl``) then fills the runtime's sphere buffer
(``envcap_dynamic_spheres.glsl``) for the shading point ``x``: first the self spheres (the two most
influential blocker bones of the triangle's provoking vertex, placed at ``x``: :func:`self_spheres`,
``self`` on), then per neighbour in that order (``neighbours``
on): its bone spheres when ``|x - centre| < NEAR_FACTOR * enclosing``, else its one sphere, until
:data:`MAX_SPHERES` are in; the runtime then keeps the ``SPHERE_CAP`` most occluding.
:func:`fragment_spheres` is the numpy twin of that fill.

Neighbour texture (:func:`neighbour_texture`), RGBA32F, row ``i`` = walker ``i``, ``2 K`` texels:
``m``: neighbour ``m``'s one sphere (centre xyz relative to the render origin, radius; radius 0:
no neighbour); ``K + m``: (enclosing radius m, the neighbour's row in the instance texture, 0, 0).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from envcap.crowd.instances import CrowdPose
from envcap.dynamic.crowd_lod import NEAR_FACTOR
from envcap.dynamic.spheres import SphereBuffer

NEIGHBOURS = 6
"""Nearest other walkers listed per walker."""
MAX_SPHERES = 48
"""Spheres a shading point gathers (the runtime's ``ENVCAP_MAX_SPHERES`` in the crowd shader)."""
SELF_SPHERES = 2
"""Blocker bones per vertex passed to the fragment shader."""
SELF_CLAMP = 0.7
"""Each own blocker sphere's radius is at most this times its centre's distance from the shading
point (``CROWD_SELF_CLAMP`` in ``crowd_frag.glsl``): a fitted sphere of the next limb holds points
of the body's surface, and unclamped it blocks half the sky there (docs/crowd.md)."""
ROW_BLOCK = 512
"""Walkers per block of the distance search (memory ``ROW_BLOCK x N`` floats)."""


def nearest_neighbours(one: NDArray[np.float64], k: int = NEIGHBOURS) -> NDArray[np.int64]:
    """``(N, k)`` for each walker the rows of its ``k`` nearest other walkers (one-sphere centres
    ``one[:, :3]``), nearest first, -1 past the crowd's size."""
    n = len(one)
    out = np.full((n, k), -1, np.int64)
    if n < 2 or k == 0:
        return out
    c = one[:, :3] - one[:, :3].mean(axis=0)
    sq = np.einsum("ij,ij->i", c, c)
    kk = min(k, n - 1)
    for a in range(0, n, ROW_BLOCK):
        d = sq[a:a + ROW_BLOCK, None] + sq[None, :] - 2.0 * c[a:a + ROW_BLOCK] @ c.T    # squared distances
        d[np.arange(len(d)), np.arange(a, a + len(d))] = np.inf
        part = np.argpartition(d, kk - 1, axis=1)[:, :kk] if kk < n else np.argsort(d, axis=1)[:, :kk]
        pd = np.take_along_axis(d, part, axis=1)
        order = np.lexsort((part, pd), axis=1)                   # by distance, ties by index
        out[a:a + ROW_BLOCK, :kk] = np.take_along_axis(part, order, axis=1)
    return out


def neighbour_texture(pose: CrowdPose, neighbours: NDArray[np.int64]) -> NDArray[np.float32]:
    """``(N, 2 K, 4)`` float32: the neighbour texture's texels (module docstring)."""
    n, k = neighbours.shape
    tex = np.zeros((n, 2 * k, 4), np.float32)
    live = neighbours >= 0
    idx = np.maximum(neighbours, 0)
    tex[:, :k, :] = np.where(live[..., None], pose.one[idx, :4], 0.0)
    tex[:, k:, 0] = np.where(live, pose.one[idx, 4], 0.0)
    tex[:, k:, 1] = np.where(live, idx, -1)
    return tex


def fragment_spheres(x: NDArray[np.float64], walker: int, self_spheres: NDArray[np.float64], pose: CrowdPose,
                     neighbours: NDArray[np.int64], *, use_self: bool, use_neighbours: bool, albedo: float,
                     max_spheres: int = MAX_SPHERES, near_factor: float = NEAR_FACTOR) -> SphereBuffer:
    """The spheres the crowd shader gathers at one shading point ``x`` ``(3,)`` (relative to the
    render origin) of ``walker`` whose vertex passed ``self_spheres`` ``(SELF_SPHERES, 4)``
    (centre, radius): the numpy twin of ``crowd_gather_spheres`` (module docstring)."""
    cs: list[NDArray] = []
    if use_self:
        cs += [s for s in np.asarray(self_spheres, np.float64).reshape(-1, 4) if s[3] > 0]
    if use_neighbours:
        for m in neighbours[walker]:
            if m < 0:
                continue
            one = pose.one[m]
            if np.linalg.norm(x - one[:3]) < near_factor * one[4]:
                cs += list(pose.spheres[m])
            else:
                cs.append(one[:4])
    cs = cs[:max_spheres]
    arr = np.array(cs, np.float64).reshape(-1, 4)
    return SphereBuffer(arr[:, :3], np.maximum(arr[:, 3], 0.0), np.full((len(arr), 3), albedo))


def self_blockers(blockers: NDArray, scores: NDArray) -> NDArray[np.int64]:
    """``(V, SELF_SPHERES)`` the blocker joints the vertex stage passes (flat) for each vertex
    (numpy twin of ``crowd_vert.glsl``): the two of highest score (``blockers``, ``scores``
    ``(V, 4)``), in joint order, -1 where the score is <= 0."""
    j = np.asarray(blockers)[:, :2].astype(np.int64)
    w = np.asarray(scores, np.float64)[:, :2]
    swap = (j[:, 1] < j[:, 0]) & (w[:, 1] > 0)
    j = np.where(swap[:, None], j[:, ::-1], j)
    w = np.where(swap[:, None], w[:, ::-1], w)
    return np.where(w > 0, j, -1)


def self_spheres(x: NDArray[np.float64], joints: NDArray[np.int64], spheres: NDArray[np.float64],
                 heads: NDArray[np.float64], clamp: float = SELF_CLAMP) -> NDArray[np.float64]:
    """``(V, SELF_SPHERES, 4)`` the own blocker spheres at shading points ``x`` ``(V, 3)`` of one
    walker, whose triangles' provoking vertices passed ``joints`` ``(V, SELF_SPHERES)``
    (:func:`self_blockers`; numpy twin of ``crowd_self_sphere`` in ``shaders/crowd/crowd_frag.glsl``):
    each bone sphere (``spheres`` ``(J, 4)`` posed, ``heads`` ``(J, 3)``) slid along its bone from
    the head ``h`` through the centre ``c`` to ``2c - h`` to the point nearest ``x``; a slid sphere
    that would hold ``x`` keeps its centre; its radius then at most ``clamp`` times the centre's
    distance from ``x`` (0: no clamp); joint -1 gives a radius-0 sphere."""
    x = np.asarray(x, np.float64).reshape(-1, 3)
    js = np.asarray(joints, np.int64).reshape(len(x), -1)
    out = np.zeros((len(x), js.shape[1], 4))
    for k in range(js.shape[1]):
        live = js[:, k] >= 0
        jj = np.maximum(js[:, k], 0)
        s, h = spheres[jj], heads[jj]
        e = 2.0 * (s[:, :3] - h)
        ee = np.einsum("ij,ij->i", e, e)
        u = np.where(ee > 0, np.clip(np.einsum("ij,ij->i", x - h, e) / np.where(ee > 0, ee, 1.0), 0.0, 1.0), 0.5)
        p = h + u[:, None] * e
        p = np.where((np.linalg.norm(x - p, axis=1) <= s[:, 3])[:, None], s[:, :3], p)
        r = s[:, 3]
        if clamp > 0:
            r = np.minimum(r, clamp * np.linalg.norm(p - x, axis=1))
        out[:, k] = np.where(live[:, None], np.c_[p, r], 0.0)
    return out
