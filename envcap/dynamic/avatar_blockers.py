"""Per vertex, the few proxy spheres (joints) of its own avatar that block it most over the
animation's keyframes (the paper's Section V).

**Blocking measure.**  The fraction of the cosine-weighted hemisphere above a vertex (position
``p``, unit normal ``n``) that a sphere ``(c, r)`` hides:

    F = (1 / pi) * integral over the sphere's cap of max(0, u.n) du    in [0, 1],

the form factor from a surface element to a sphere (the light a white diffuse vertex loses from a
uniform sky).  Closed form (Howell's catalogue, planar element to sphere; Snyder 1996), with
``s = r / l`` (``l = |c - p|``), ``gamma`` the angle between ``n`` and ``c - p``:

* ``cos gamma >= s``: the whole cap is above the horizon, ``F = s^2 cos gamma``;
* ``cos gamma <= -s``: below it, ``F = 0``;
* otherwise (the horizon cuts the cap), with ``x = sqrt(1/s^2 - 1)``, ``y = -x cot gamma``:
  ``pi F = s^2 (cos gamma acos y - x sin gamma sqrt(1 - y^2)) + atan(sin gamma sqrt(1 - y^2) / x)``;
* ``l = r`` (``x = 0``): ``F = (1 + cos gamma) / 2``; ``l < r`` (inside): ``F = 1``; ``r <= 0``: 0.

Checked against the float64 cap quadrature (:func:`envcap.dynamic.quadrature.cap_lobe_integral`
at ``w = 1``) in ``tests/dynamic/test_avatar_blockers.py``.

**Selection.**  ``F`` for every (vertex, joint, keyframe), the vertex and the spheres posed by the
skin at each keyframe time of the animation (the bind pose when there is none); reduced over
keyframes by the mean (default: taking the ``k`` largest means minimises the time-averaged light
the omitted spheres would have blocked, blocking taken as additive) or the max (the worst frame).
A vertex's own joints, those with a skinning weight ``> exclude_weight`` (default 0: every joint
it is skinned to), are excluded, as in the paper: a limb's own sphere contains or touches its
surface and the normal's hemisphere already accounts for it.  The ``k`` (<= 4) best joints in
decreasing score (ties: lower joint index); slots without a blocker (score 0) hold joint 0 and
score 0, as glTF's ``JOINTS_0`` does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.dynamic.gltf_skin import SkinnedAvatar, joint_matrices, skin
from envcap.dynamic.proxy_spheres import ProxySpheres, joint_weight_matrix, pose_spheres

MAX_BLOCKERS = 4
"""At most this many blockers per vertex (one glTF VEC4 attribute)."""
REDUCTIONS = ("mean", "max")


def sphere_form_factor(points: ArrayLike, normals: ArrayLike, centers: ArrayLike, radii: ArrayLike) -> NDArray[np.float64]:
    """``F`` (module docstring) for broadcastable ``points``, unit ``normals``, ``centers``
    ``(..., 3)`` (m) and ``radii`` ``(...)`` (m); float64, in [0, 1]."""
    p, n, c = (np.asarray(a, dtype=np.float64) for a in (points, normals, centers))
    r = np.asarray(radii, dtype=np.float64)
    v = c - p
    ell = np.sqrt(np.sum(v * v, axis=-1))
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_g = np.clip(np.sum(n * v, axis=-1) / ell, -1.0, 1.0)
        s = np.minimum(r / ell, 1.0)
        sin_g = np.sqrt(np.maximum(1.0 - cos_g * cos_g, 0.0))
        x = np.sqrt(np.maximum((ell - r) * (ell + r), 0.0)) / r
        y = np.clip(-x * cos_g / np.where(sin_g > 0, sin_g, 1.0), -1.0, 1.0)
        root = sin_g * np.sqrt(np.maximum(1.0 - y * y, 0.0))
        partial = (s * s * (cos_g * np.arccos(y) - x * root) + np.arctan2(root, x)) / np.pi
    f = np.where(cos_g >= s, s * s * cos_g, np.where(cos_g <= -s, 0.0, partial))
    f = np.where(ell < r, 1.0, f)
    f = np.where((r > 0) & np.isfinite(f), f, 0.0)
    return np.clip(f, 0.0, 1.0)


@dataclass(frozen=True)
class Blockers:
    """``joints`` ``(V, k)`` joint indices (skin order), ``scores`` ``(V, k)`` their reduced ``F``
    (decreasing; 0 in unused slots); ``per_frame`` ``(K, V, J)`` ``F`` of every joint at every
    keyframe (own joints set to 0); ``keyframes`` ``(K,)`` s; ``reduce``, ``exclude_weight``."""

    joints: NDArray[np.int64]
    scores: NDArray[np.float64]
    per_frame: NDArray[np.float64]
    keyframes: NDArray[np.float64]
    reduce: str
    exclude_weight: float


def own_joint_mask(avatar: SkinnedAvatar, exclude_weight: float = 0.0) -> NDArray[np.bool_]:
    """``(V, J)`` True where the vertex's weight to the joint exceeds ``exclude_weight``."""
    return joint_weight_matrix(avatar) > exclude_weight


def check_options(k: int, reduce: str, exclude_weight: float) -> None:
    """Raise ``ValueError`` naming the bad one of :func:`select_blockers`'s options."""
    if not isinstance(k, (int, np.integer)) or not 1 <= k <= MAX_BLOCKERS:
        raise ValueError(f"k must be an integer from 1 to {MAX_BLOCKERS} (one VEC4 attribute), got {k!r}")
    if reduce not in REDUCTIONS:
        raise ValueError(f"reduce must be one of {', '.join(REDUCTIONS)}, got {reduce!r}")
    if not np.isfinite(exclude_weight) or not 0 <= exclude_weight < 1:
        raise ValueError(f"exclude_weight must be in [0, 1), got {exclude_weight!r}")


def select_blockers(avatar: SkinnedAvatar, spheres: ProxySpheres, k: int = MAX_BLOCKERS, animation: int | None = 0,
                    reduce: str = "mean", exclude_weight: float = 0.0) -> Blockers:
    """The ``k`` most-blocking joints of every vertex over the keyframes of ``animation`` (None,
    or an avatar without animations: the rest pose only)."""
    check_options(k, reduce, exclude_weight)
    if animation is not None and not avatar.animations:
        animation = None
    if animation is not None and not 0 <= animation < len(avatar.animations):
        raise ValueError(f"animation {animation} does not exist (the avatar has {len(avatar.animations)})")
    times = avatar.animations[animation].keyframes if animation is not None else np.zeros(1)
    own = own_joint_mask(avatar, exclude_weight)
    frames = np.zeros((len(times), len(avatar.positions), avatar.joint_count))
    for i, t in enumerate(times):
        pts, nrm = skin(joint_matrices(avatar, animation, float(t)), avatar)
        centers, radii = pose_spheres(spheres, avatar, animation, float(t))
        frames[i] = sphere_form_factor(pts[:, None], nrm[:, None], centers[None], radii[None])
    frames[:, own] = 0.0
    score = frames.mean(axis=0) if reduce == "mean" else frames.max(axis=0)
    order = np.argsort(-score, axis=1, kind="stable")[:, :k]
    best = np.take_along_axis(score, order, axis=1)
    joints = np.where(best > 0, order, 0)
    return Blockers(joints.astype(np.int64), np.where(best > 0, best, 0.0), frames, np.asarray(times, np.float64),
                    reduce, float(exclude_weight))
