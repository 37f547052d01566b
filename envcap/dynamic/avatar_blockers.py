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

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.budget import check_bytes
from envcap.core.checks import format_number
from envcap.dynamic.gltf_skin import SkinnedAvatar, joint_matrices, skin
from envcap.dynamic.proxy_spheres import ProxySpheres, joint_weight_matrix, pose_spheres

MAX_BLOCKERS = 4
"""At most this many blockers per vertex (one glTF VEC4 attribute)."""
REDUCTIONS = ("mean", "max")


def sphere_form_factor(points: ArrayLike, normals: ArrayLike, centers: ArrayLike, radii: ArrayLike) -> NDArray[np.float64]:
    """``F`` (module docstring) for broadcastable ``points``, unit ``normals``, ``centers``
    ``(..., 3)`` (m) and ``radii`` ``(...)`` (m); float64, in [0, 1].  The horizon-cut branch
    (inverse trigonometry) is evaluated only where it applies: a far sphere costs a few
    multiplications."""
    p, n, c = (np.asarray(a, dtype=np.float64) for a in (points, normals, centers))
    r = np.asarray(radii, dtype=np.float64)
    v = c - p
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]   # sums of three written out: the order of np.sum, faster
    ell = np.sqrt(vx * vx + vy * vy + vz * vz)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_g = np.clip((n[..., 0] * vx + n[..., 1] * vy + n[..., 2] * vz) / ell, -1.0, 1.0)
        cos_g, r, ell = np.broadcast_arrays(cos_g, r, ell)
        s = np.minimum(r / ell, 1.0)
        f = np.where(cos_g >= s, s * s * cos_g, 0.0)
        cut = (cos_g < s) & (cos_g > -s)
        if np.any(cut):
            cg, sc, rc, lc = cos_g[cut], s[cut], r[cut], ell[cut]
            sin_g = np.sqrt(np.maximum(1.0 - cg * cg, 0.0))
            x = np.sqrt(np.maximum((lc - rc) * (lc + rc), 0.0)) / rc
            y = np.clip(-x * cg / np.where(sin_g > 0, sin_g, 1.0), -1.0, 1.0)
            root = sin_g * np.sqrt(np.maximum(1.0 - y * y, 0.0))
            f[cut] = (sc * sc * (cg * np.arccos(y) - x * root) + np.arctan2(root, x)) / np.pi
    f = np.where(ell < r, 1.0, f)
    f = np.where((r > 0) & np.isfinite(f), f, 0.0)
    return np.clip(f, 0.0, 1.0)


BLOCK_PAIRS = 1 << 17
"""(vertex, joint) pairs evaluated at once: the vertices go through :func:`select_blockers` in
blocks of ``max(1, BLOCK_PAIRS // J)``, so that its temporaries stay near ``BLOCK_PAIRS x``
:data:`BYTES_PER_PAIR` (~25 MiB) whatever the avatar's size."""
BYTES_PER_PAIR = 200
"""Peak bytes per (vertex, joint) pair of a block: the form factor's float64 temporaries (measured
~150 with ``tracemalloc``), the reduction and the own-joint mask."""


@dataclass(frozen=True)
class Blockers:
    """``joints`` ``(V, k)`` joint indices (skin order), ``scores`` ``(V, k)`` their reduced ``F``
    (decreasing; 0 in unused slots); ``per_frame`` ``(K, V, J)`` ``F`` of every joint at every
    keyframe (own joints set to 0), only when asked for (``keep_frames``: ``K x V x J`` float64,
    checked against the memory limit), else ``None``; ``keyframes`` ``(K,)`` s; ``reduce``,
    ``exclude_weight``."""

    joints: NDArray[np.int64]
    scores: NDArray[np.float64]
    per_frame: NDArray[np.float64] | None
    keyframes: NDArray[np.float64]
    reduce: str
    exclude_weight: float


def own_joint_mask(avatar: SkinnedAvatar, exclude_weight: float = 0.0, rows: slice = slice(None)) -> NDArray[np.bool_]:
    """``(n, J)`` True where the weight of a vertex of ``rows`` (default all) to the joint exceeds ``exclude_weight``."""
    return joint_weight_matrix(avatar, rows) > exclude_weight


def check_options(k: int, reduce: str, exclude_weight: float) -> None:
    """Raise ``ValueError`` naming the bad one of :func:`select_blockers`'s options."""
    if not isinstance(k, (int, np.integer)) or not 1 <= k <= MAX_BLOCKERS:
        raise ValueError(f"k (--k) must be an integer from 1 to {MAX_BLOCKERS} (one VEC4 attribute), got {k!r}")
    if reduce not in REDUCTIONS:
        raise ValueError(f"reduce (--reduce) must be one of {', '.join(REDUCTIONS)}, got {reduce!r}")
    if not np.isfinite(exclude_weight) or not 0 <= exclude_weight < 1:
        raise ValueError(f"exclude_weight (--exclude-weight) must be in [0, 1), got {format_number(exclude_weight)}")


def block_rows(joint_count: int, pairs: int = BLOCK_PAIRS) -> int:
    """Vertices per block of :func:`select_blockers` for ``joint_count`` joints."""
    return max(1, int(pairs) // max(1, int(joint_count)))


def top_k(score: NDArray[np.float64], k: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Per row of ``score`` ``(n, J)`` (values >= 0), the ``k`` largest positive entries in
    decreasing order, ties by lower column: ``(columns (n, k), values (n, k))``, slots without a
    positive entry ``(0, 0.0)``; ``min(k, J)`` columns.  The same as a stable sort of each row, in
    ``O(J)`` a row (a partition finds the k-th largest value; only the entries at or above it are
    sorted)."""
    n, width = score.shape
    k = min(k, width)
    kth = (-np.partition(-score, k - 1, axis=1)[:, k - 1:k]) if k < width else score.min(axis=1, keepdims=True)
    rows, cols = np.nonzero((score >= kth) & (score > 0))
    vals = score[rows, cols]
    order = np.lexsort((cols, -vals, rows))
    rows, cols, vals = rows[order], cols[order], vals[order]
    rank = np.arange(len(rows)) - np.searchsorted(rows, np.arange(n))[rows]
    keep = rank < k
    joints = np.zeros((n, k), dtype=np.int64)
    values = np.zeros((n, k))
    joints[rows[keep], rank[keep]] = cols[keep]
    values[rows[keep], rank[keep]] = vals[keep]
    return joints, values


def select_blockers(avatar: SkinnedAvatar, spheres: ProxySpheres, k: int = MAX_BLOCKERS, animation: int | None = 0,
                    reduce: str = "mean", exclude_weight: float = 0.0, *, keep_frames: bool = False,
                    pairs: int = BLOCK_PAIRS, progress: Callable[[int], None] | None = None) -> Blockers:
    """The ``k`` most-blocking joints of every vertex over the keyframes of ``animation`` (None,
    or an avatar without animations: the rest pose only).

    Memory: the vertices go in blocks of ``pairs // J`` (:func:`block_rows`), each block posed at
    every keyframe, its ``F`` reduced and its ``k`` best kept, so the peak is ``pairs x``
    :data:`BYTES_PER_PAIR` bytes plus ``O(V k + K J)``, not ``K x V x J`` (the result does not
    depend on ``pairs``).  ``keep_frames``: also return every ``F`` (``per_frame``; checked
    against the memory limit).  ``progress(n)``: called after each block with its vertex count."""
    check_options(k, reduce, exclude_weight)
    if animation is not None and not avatar.animations:
        animation = None
    if animation is not None and not 0 <= animation < len(avatar.animations):
        raise ValueError(f"animation {animation} (--animation) does not exist (the avatar has {len(avatar.animations)}, "
                         f"numbered from 0)")
    times = avatar.animations[animation].keyframes if animation is not None else np.zeros(1)
    count, joints = len(avatar.positions), avatar.joint_count
    poses = [(joint_matrices(avatar, animation, float(t)), *pose_spheres(spheres, avatar, animation, float(t)))
             for t in times]
    per_frame = None
    if keep_frames:
        check_bytes(f"per-keyframe blocking of {count:,} vertices x {joints:,} joints x {len(times)} keyframes",
                    8.0 * len(times) * count * joints, "keep_frames=False")
        per_frame = np.zeros((len(times), count, joints))
    best_joints = np.zeros((count, min(k, joints)), dtype=np.int64)
    best_scores = np.zeros((count, min(k, joints)))
    step = block_rows(joints, pairs)
    for a in range(0, count, step):
        rows = slice(a, min(a + step, count))
        own = own_joint_mask(avatar, exclude_weight, rows)
        total = None
        for i, (mats, centers, radii) in enumerate(poses):
            pts, nrm = skin(mats, avatar, rows)
            f = sphere_form_factor(pts[:, None], nrm[:, None], centers[None], radii[None])
            f[own] = 0.0
            if per_frame is not None:
                per_frame[i, rows] = f
            total = f if total is None else (total + f if reduce == "mean" else np.maximum(total, f))
        best_joints[rows], best_scores[rows] = top_k(total / len(times) if reduce == "mean" else total, k)
        if progress is not None:
            progress(rows.stop - rows.start)
    return Blockers(best_joints, best_scores, per_frame, np.asarray(times, np.float64), reduce, float(exclude_weight))
