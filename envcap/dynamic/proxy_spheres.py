"""Proxy spheres of a skinned avatar, one per joint (the paper's Section V), in the joint's own
frame so that they move with the animation.

**Which vertices.**  A vertex belongs to the joint that carries its largest skinning weight (the
weights of repeated ``JOINTS_0`` slots summed; ties: the lower joint index): every vertex belongs
to exactly one joint, a vertex with a weight >= 0.5 to its joint.  The bone's vertices are taken to
its bind frame, ``p = IBM_j v`` (joint-local, m).

**Which sphere.**  Centre: the volume centroid of their convex hull.  Radius: the one of equal mean
projected area, ``r = sqrt(S / (4 pi))`` with ``S`` the hull's surface area.  By Cauchy's formula a
convex body's projected area averaged over view directions is ``S / 4``, and a sphere's is
``pi r^2``: seen from a random direction at a distance, the sphere blocks the same solid angle as
the limb's hull on average (a capsule of length ``L``, radius ``a`` gets
``r = sqrt(a (a + L / 2))``, between its thickness and its half-length; the bounding sphere would
over-block a thin limb by ``(L / 2a)^2``).  A joint with fewer than 4 vertices, or with a flat
hull, gets radius 0 (no sphere: it blocks nothing).

**Posed.**  At time ``t`` a sphere's centre is ``G_j(t) c`` and its radius ``r |det G_j|^(1/3)``
(exact for rigid joints and uniform scale).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from envcap.dynamic.gltf_skin import SkinnedAvatar, global_matrices


@dataclass(frozen=True)
class ProxySpheres:
    """One sphere per joint: ``centers`` ``(J, 3)`` in the joint's bind frame (m), ``radii``
    ``(J,)`` m (0: no sphere), ``vertex_counts`` ``(J,)`` vertices the fit used, ``owner``
    ``(V,)`` the joint each vertex belongs to."""

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    vertex_counts: NDArray[np.int64]
    owner: NDArray[np.int64]


def joint_weight_matrix(avatar: SkinnedAvatar, rows: slice = slice(None)) -> NDArray[np.float64]:
    """``(n, J)`` skinning weight of the vertices ``rows`` (default all) to every joint (slots
    naming one joint summed).  ``n x J`` float64: callers with many joints take a slice at a time."""
    joints, weights = avatar.joints[rows], avatar.weights[rows]
    w = np.zeros((len(joints), avatar.joint_count))
    np.add.at(w, (np.repeat(np.arange(len(joints)), 4), joints.reshape(-1)), weights.reshape(-1))
    return w


def owner_joints(avatar: SkinnedAvatar) -> NDArray[np.int64]:
    """``(V,)`` the joint carrying each vertex's largest skinning weight (repeated slots summed;
    ties: the lower joint index), from the four slots alone (``V x 16`` work, not ``V x J``)."""
    j, w = avatar.joints.astype(np.int64), avatar.weights
    summed = np.where(j[:, :, None] == j[:, None, :], w[:, None, :], 0.0).sum(axis=2)  # (V, 4): slot's joint total
    best = summed.max(axis=1, keepdims=True)
    return np.where(summed == best, j, np.iinfo(np.int64).max).min(axis=1)


def hull_sphere(points: NDArray) -> tuple[NDArray[np.float64], float]:
    """``(centre, radius)``: hull volume centroid and the radius of equal mean projected area
    (``sqrt(area / 4 pi)``); ``radius = 0`` (centre the mean) for < 4 points or a flat hull."""
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) == 0:
        return np.zeros(3), 0.0
    if len(pts) < 4:
        return pts.mean(axis=0), 0.0
    from scipy.spatial import ConvexHull, QhullError  # heavy (~0.4 s): only when spheres are fitted

    try:
        hull = ConvexHull(pts)
    except QhullError:
        return pts.mean(axis=0), 0.0
    if hull.volume <= 1e-15 * max(hull.area, 1e-300) ** 1.5:
        return pts.mean(axis=0), 0.0
    ref = pts[hull.vertices].mean(axis=0)
    tri = pts[hull.simplices]
    vol = np.abs(np.einsum("ij,ij->i", tri[:, 0] - ref, np.cross(tri[:, 1] - ref, tri[:, 2] - ref))) / 6
    cen = (tri.sum(axis=1) + ref) / 4
    return (vol[:, None] * cen).sum(axis=0) / vol.sum(), float(np.sqrt(hull.area / (4 * np.pi)))


def fit_proxy_spheres(avatar: SkinnedAvatar) -> ProxySpheres:
    """Fit the proxy sphere of every joint of ``avatar`` (rule in the module docstring)."""
    owner = owner_joints(avatar)
    homog = np.concatenate([avatar.positions, np.ones((len(avatar.positions), 1))], axis=1)
    centers = np.zeros((avatar.joint_count, 3))
    radii = np.zeros(avatar.joint_count)
    counts = np.bincount(owner, minlength=avatar.joint_count).astype(np.int64)
    order = np.argsort(owner, kind="stable")   # each joint's vertices in their file order
    ends = np.cumsum(counts)
    for j in range(avatar.joint_count):
        local = (homog[order[ends[j] - counts[j]:ends[j]]] @ avatar.inverse_bind[j].T)[:, :3]
        centers[j], radii[j] = hull_sphere(local)
    return ProxySpheres(centers, radii, counts, owner)


def pose_spheres(spheres: ProxySpheres, avatar: SkinnedAvatar, animation: int | None = None,
                 time: float = 0.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World ``(centers (J, 3), radii (J,))`` of the proxy spheres at ``time`` s of ``animation``
    (None: the bind pose's joint transforms, i.e. the rest pose)."""
    g = global_matrices(avatar, animation, time)[avatar.joint_nodes]
    centers = np.einsum("jab,jb->ja", g[:, :3, :3], spheres.centers) + g[:, :3, 3]
    scale = np.abs(np.linalg.det(g[:, :3, :3])) ** (1.0 / 3.0)
    return centers, spheres.radii * scale
