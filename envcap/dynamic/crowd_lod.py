"""Levels of detail for the other avatars of a crowd (the paper's Section VI): one sphere for a far
avatar, its proxy (bone) spheres for a near one.

**The one sphere** of an avatar at a pose (``avatar_sphere``): centre the projected-area-weighted
mean of the bone spheres' centres, ``sum r_j^2 c_j / sum r_j^2``; radius ``sqrt(A / pi)`` with ``A``
the projected area of the *union* of the bone spheres averaged over ``DIRECTIONS`` view
directions (a Fibonacci sphere; the union's area exact, by Green's theorem over its boundary arcs).  It
is the sphere that, from afar, hides the same solid angle as the bone spheres on average; overlaps
(arms against the torso) are counted once, which a sum of the spheres' areas would not do.  Also
returned: ``enclosing``, the radius about that centre that contains every bone sphere.

**The rule** (``use_bone_spheres``): a shading point at distance ``d`` from the avatar's one-sphere
centre uses the bone spheres when ``d < NEAR_FACTOR * enclosing``, the one sphere otherwise.
``NEAR_FACTOR = 3`` is measured (``docs/images/make_avatar_figures.py``, ``docs/dynamic.md``): for
the test avatar at its keyframes, beyond ``3 R`` the one sphere's form factor is within 0.005 of
the union's (brute force over directions), with the normal facing the avatar (the worst case).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

DIRECTIONS = 32
"""View directions over which the union's projected area is averaged."""
NEAR_FACTOR = 3.0
"""Bone spheres within ``NEAR_FACTOR`` enclosing radii of the avatar's centre, one sphere beyond."""


@dataclass(frozen=True)
class AvatarSphere:
    """One avatar as one sphere: ``center`` ``(3,)`` m, ``radius`` m (equal mean projected area),
    ``enclosing`` m (contains every bone sphere, about ``center``)."""

    center: NDArray[np.float64]
    radius: float
    enclosing: float


def fibonacci_directions(n: int) -> NDArray[np.float64]:
    """``n`` unit vectors spread evenly over the sphere (golden-angle spiral), ``(n, 3)``."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5**0.5) * i
    rho = np.sqrt(1 - z * z)
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


def union_disk_area(xy: NDArray, radii: NDArray) -> float:
    """Exact area (m^2) of a union of disks (centres ``(n, 2)``, radii ``(n,)``): Green's theorem
    over the boundary arcs no other disk covers, ``A = 1/2 sum over arcs of (x dy - y dx)``."""
    xy, radii = np.asarray(xy, dtype=np.float64), np.asarray(radii, dtype=np.float64)
    two_pi, area = 2 * np.pi, 0.0
    # Only a disk whose x lies within r + max radius of disk i's can cover or cut it: look at the
    # window of those (by sorted x) instead of all n, the same disks in the same order.
    by_x = np.argsort(xy[:, 0], kind="stable")
    sorted_x = xy[by_x, 0]
    reach = float(np.max(radii, initial=0.0))
    for i, (c, r) in enumerate(zip(xy, radii)):
        if r <= 0:
            continue
        lo = int(np.searchsorted(sorted_x, c[0] - r - reach, side="left"))
        hi = int(np.searchsorted(sorted_x, c[0] + r + reach, side="right"))
        idx = np.sort(by_x[lo:hi])
        delta = xy[idx] - c
        d = np.hypot(delta[:, 0], delta[:, 1])
        radii_w = radii[idx]
        other = (idx != i) & (radii_w > 0)
        # inside disk j (of two equal disks, the first one counts)
        if np.any(other & (d + r <= radii_w) & ((d > 0) | (radii_w > r) | (idx < i))):
            continue
        cut = other & (d < r + radii_w) & (d + radii_w > r)
        mid = np.arctan2(delta[cut, 1], delta[cut, 0]) % two_pi
        half = np.arccos(np.clip((r * r + d[cut] ** 2 - radii_w[cut] ** 2) / (2 * r * d[cut]), -1.0, 1.0))
        lo, hi = (mid - half) % two_pi, (mid + half) % two_pi
        wrap = lo >= hi
        cover = sorted(zip(np.r_[lo[~wrap], lo[wrap], np.zeros(wrap.sum())], np.r_[hi[~wrap], np.full(wrap.sum(), two_pi), hi[wrap]]))
        free, at = [], 0.0
        for a, b in cover:
            if a > at:
                free.append((at, a))
            at = max(at, b)
        if at < two_pi:
            free.append((at, two_pi))
        for a, b in free:
            area += 0.5 * (r * r * (b - a) + r * (c[0] * (np.sin(b) - np.sin(a)) - c[1] * (np.cos(b) - np.cos(a))))
    return float(area)


def union_projected_area(centers: NDArray, radii: NDArray, direction: NDArray) -> float:
    """Area (m^2) of the union of the disks the spheres project to along ``direction``."""
    d = direction / np.linalg.norm(direction)
    ref = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(d, ref)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    return union_disk_area(np.stack([centers @ e1, centers @ e2], axis=1), radii)


def avatar_sphere(centers: ArrayLike, radii: ArrayLike, directions: int = DIRECTIONS) -> AvatarSphere:
    """The one sphere of an avatar whose posed bone spheres are ``centers`` ``(J, 3)``, ``radii`` ``(J,)`` m."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if len(c) != len(r) or not np.all(np.isfinite(c)) or not np.all(np.isfinite(r)) or np.any(r < 0):
        raise ValueError("avatar_sphere needs finite centers (J, 3) and radii (J,) >= 0 of equal length")
    keep = r > 0
    if not keep.any():
        raise ValueError("avatar_sphere: the avatar has no sphere of positive radius")
    c, r = c[keep], r[keep]
    center = (r[:, None] ** 2 * c).sum(axis=0) / (r**2).sum()
    area = np.mean([union_projected_area(c, r, d) for d in fibonacci_directions(directions)])
    enclosing = float(np.max(np.linalg.norm(c - center, axis=1) + r))
    return AvatarSphere(center, float(np.sqrt(area / np.pi)), enclosing)


def use_bone_spheres(points: ArrayLike, sphere: AvatarSphere, near_factor: float = NEAR_FACTOR) -> NDArray[np.bool_]:
    """``(...)`` True where a shading point ``(..., 3)`` is near enough to use the bone spheres."""
    p = np.asarray(points, dtype=np.float64)
    return np.linalg.norm(p - sphere.center, axis=-1) < near_factor * sphere.enclosing


def crowd_spheres(point: ArrayLike, bone_spheres: list[tuple[NDArray, NDArray]], avatar_spheres: list[AvatarSphere],
                  near_factor: float = NEAR_FACTOR) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The spheres one shading point ``(3,)`` sees of a crowd: for each avatar ``i`` its bone
    spheres ``bone_spheres[i] = (centers (J, 3), radii (J,))`` when near, else
    ``avatar_spheres[i]``; returns ``(centers (S, 3), radii (S,))`` m."""
    if len(bone_spheres) != len(avatar_spheres):
        raise ValueError(f"{len(bone_spheres)} bone-sphere sets for {len(avatar_spheres)} avatar spheres")
    cs, rs = [np.zeros((0, 3))], [np.zeros(0)]
    for (c, r), one in zip(bone_spheres, avatar_spheres):
        if use_bone_spheres(point, one, near_factor):
            cs.append(np.asarray(c, np.float64).reshape(-1, 3)), rs.append(np.asarray(r, np.float64).reshape(-1))
        else:
            cs.append(one.center[None]), rs.append(np.array([one.radius]))
    return np.concatenate(cs), np.concatenate(rs)
