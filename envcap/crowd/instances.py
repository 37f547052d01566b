"""Each walker's skin per frame: its joint matrices, posed bone spheres and bone heads, packed
into one RGBA32F texture for instanced GPU skinning (``shaders/crowd/crowd_vert.glsl``).

The avatar's gait is sampled once (:class:`AvatarCycle`: ``samples`` poses over its animation's
keyframe range, joint matrices ``G_j IBM_j``, the proxy spheres posed in the avatar's frame, each
joint's head ``G_j (0, 0, 0)`` and the one sphere of :func:`envcap.dynamic.crowd_lod.avatar_sphere`);
a walker at time ``t`` takes the sample nearest its cycle time ``phase * period + t * speed /
NOMINAL_SPEED`` (the gait speeds up with the walk), posed by its root (turn about +Y, move to its
feet).  Instance texture (:func:`instance_texture`), row ``i`` = walker ``i``, ``6 J`` texels:

* ``4 j + c`` (c = 0..3): column ``c`` of walker ``i``'s joint matrix ``j`` (root included;
  positions relative to the render origin);
* ``4 J + j``: bone sphere ``j``: centre xyz (m, relative to the render origin), radius w (m);
* ``5 J + j``: bone head ``j``: xyz (m, relative), w = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from envcap.crowd.walkers import Walkers, yaw_matrices
from envcap.dynamic.crowd_lod import avatar_sphere
from envcap.dynamic.gltf_skin import SkinnedAvatar, global_matrices
from envcap.dynamic.proxy_spheres import ProxySpheres

NOMINAL_SPEED = 1.3
"""Walking speed (m/s) at which the avatar's animation plays at its own rate."""
SAMPLES = 16
"""Poses sampled over the gait cycle."""
TEXELS_PER_JOINT = 6
"""Texels per joint in a row of the instance texture (module docstring)."""


@dataclass(frozen=True)
class AvatarCycle:
    """The avatar's gait sampled at ``times`` ``(S,)`` s: ``joints`` ``(S, J, 4, 4)`` joint
    matrices, ``spheres`` ``(S, J, 4)`` posed bone spheres (centre m, radius m; avatar frame),
    ``heads`` ``(S, J, 3)`` joint heads, ``one`` ``(S, 5)`` the one sphere (centre, radius,
    enclosing radius), ``period`` s (0: no animation, the rest pose)."""

    avatar: SkinnedAvatar
    times: NDArray[np.float64]
    joints: NDArray[np.float64]
    spheres: NDArray[np.float64]
    heads: NDArray[np.float64]
    one: NDArray[np.float64]
    period: float

    @staticmethod
    def of(avatar: SkinnedAvatar, spheres: ProxySpheres, samples: int = SAMPLES, animation: int = 0) -> "AvatarCycle":
        """Sample ``avatar``'s ``animation`` (its rest pose when it has none) ``samples`` times
        (kept for the last few avatars of the process: the same objects give the same cycle)."""
        key = (id(avatar), id(spheres), samples, animation)
        hit = _CYCLES.get(key)
        if hit is not None and hit[0] is avatar and hit[1] is spheres:
            return hit[2]
        cycle = AvatarCycle._sample(avatar, spheres, samples, animation)
        if len(_CYCLES) >= 4:
            _CYCLES.pop(next(iter(_CYCLES)))
        _CYCLES[key] = (avatar, spheres, cycle)
        return cycle

    @staticmethod
    def _sample(avatar: SkinnedAvatar, spheres: ProxySpheres, samples: int, animation: int) -> "AvatarCycle":
        if avatar.animations:
            keys = avatar.animations[animation].keyframes
            t0, period = float(keys[0]), float(keys[-1] - keys[0])
        else:
            t0, period = 0.0, 0.0
        n = samples if period > 0 else 1
        times = t0 + period * np.arange(n) / n
        joints, sph, heads, one = [], [], [], []
        for t in times:
            g = global_matrices(avatar, animation if avatar.animations else None, float(t))
            gj = g[avatar.joint_nodes]
            joints.append(gj @ avatar.inverse_bind)
            c = np.einsum("jab,jb->ja", gj[:, :3, :3], spheres.centers) + gj[:, :3, 3]
            r = spheres.radii * np.abs(np.linalg.det(gj[:, :3, :3])) ** (1.0 / 3.0)
            sph.append(np.concatenate([c, r[:, None]], axis=1))
            heads.append(gj[:, :3, 3])
            o = avatar_sphere(c, r)
            one.append(np.r_[o.center, o.radius, o.enclosing])
        return AvatarCycle(avatar, times, np.array(joints), np.array(sph), np.array(heads), np.array(one), period)

    def sample_of(self, walkers: Walkers, time: float) -> NDArray[np.int64]:
        """``(N,)`` the sample each walker shows at ``time`` s (nearest in its cycle)."""
        n = len(self.times)
        if n == 1:
            return np.zeros(len(walkers), np.int64)
        cycle = walkers.phase + float(time) * walkers.speed / NOMINAL_SPEED / self.period
        return np.mod(np.round(np.mod(cycle, 1.0) * n).astype(np.int64), n)


_CYCLES: dict[tuple[int, int, int, int], tuple[SkinnedAvatar, ProxySpheres, AvatarCycle]] = {}
"""Cycles sampled in this process (holding their avatar and spheres, so an id is never reused)."""


@dataclass(frozen=True)
class CrowdPose:
    """The crowd at one time, world frame minus ``origin`` ((3,) float64 m, the render origin):
    ``roots`` ``(N, 4, 4)``, ``joints`` ``(N, J, 4, 4)``, ``spheres`` ``(N, J, 4)``, ``heads``
    ``(N, J, 3)``, ``one`` ``(N, 5)`` (centre, radius, enclosing), ``feet`` ``(N, 3)`` world m
    (absolute), ``samples`` ``(N,)``."""

    origin: NDArray[np.float64]
    roots: NDArray[np.float64]
    joints: NDArray[np.float64]
    spheres: NDArray[np.float64]
    heads: NDArray[np.float64]
    one: NDArray[np.float64]
    feet: NDArray[np.float64]
    samples: NDArray[np.int64]


def pose_crowd(walkers: Walkers, cycle: AvatarCycle, time: float, origin: NDArray[np.float64]) -> CrowdPose:
    """The walkers at ``time`` s (:class:`CrowdPose`), relative to the render ``origin``."""
    feet = walkers.positions(time)
    roots = yaw_matrices(walkers.headings(), feet - origin)
    k = cycle.sample_of(walkers, time)
    joints = roots[:, None] @ cycle.joints[k]
    rot, move = roots[:, None, :3, :3], roots[:, None, :3, 3]
    c = np.einsum("njab,njb->nja", rot, cycle.spheres[k, :, :3]) + move
    heads = np.einsum("njab,njb->nja", rot, cycle.heads[k]) + move
    spheres = np.concatenate([c, cycle.spheres[k, :, 3:]], axis=2)
    oc = np.einsum("nab,nb->na", roots[:, :3, :3], cycle.one[k, :3]) + roots[:, :3, 3]
    one = np.concatenate([oc, cycle.one[k, 3:]], axis=1)
    return CrowdPose(np.asarray(origin, np.float64), roots, joints, spheres, heads, one, feet, k)


def instance_texture(pose: CrowdPose) -> NDArray[np.float32]:
    """``(N, 6 J, 4)`` float32: the instance texture's texels (module docstring)."""
    n, j = pose.joints.shape[:2]
    cols = np.swapaxes(pose.joints, 2, 3).reshape(n, 4 * j, 4)          # column c of matrix j at 4 j + c
    heads = np.concatenate([pose.heads, np.zeros((n, j, 1))], axis=2)
    return np.concatenate([cols, pose.spheres, heads], axis=1).astype(np.float32)
