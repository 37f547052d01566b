"""Per-vertex blocking bones (issue 14, Section V): the sphere form factor against the float64 cap
quadrature, and the top-k choice against a brute force over the keyframes (posed with the
closed-form walk, blocking counted ray by ray)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_avatar_skin import walk_globals

from envcap.dynamic.avatar_blockers import select_blockers, sphere_form_factor
from envcap.dynamic.avatar_synthetic import BONES, KEYFRAMES, rest_positions, walker_gltf
from envcap.dynamic.gltf_skin import avatar_from_gltf
from envcap.dynamic.proxy_spheres import fit_proxy_spheres
from envcap.dynamic.quadrature import cap_lobe_integral


def test_form_factor_matches_the_cap_quadrature():
    worst = 0.0
    for s in (1e-3, 0.3, 0.9, 0.999):
        theta = math.asin(s)
        # gamma across the three regimes, and exactly at their borders (cos gamma = +- s)
        for gamma in (*np.linspace(0, math.pi, 9), math.pi / 2 - theta, math.pi / 2 + theta, 1.3):
            want = cap_lobe_integral(theta, gamma, 1.0) / math.pi
            got = sphere_form_factor([0, 0, 0], [0, 0, 1], [3 * math.sin(gamma), 0, 3 * math.cos(gamma)], 3 * s)
            worst = max(worst, abs(float(got) - want))
    assert worst < 1e-9
    o, n = np.zeros(3), np.array([0.0, 0, 1])
    assert sphere_form_factor(o, n, [1, 0, 0], 1.0) == pytest.approx(0.5, abs=1e-15)  # touching, on the horizon
    assert sphere_form_factor(o, n, [0, 0, 1], 1.0) == 1.0  # touching above: the whole hemisphere
    assert sphere_form_factor(o, n, [0, 0, -1], 1.0) == 0.0  # touching below
    assert sphere_form_factor(o, n, [0.1, 0, 0], 1.0) == 1.0  # inside
    assert sphere_form_factor(o, n, [0, 0, 0], 1.0) == 1.0  # centre on the point
    assert sphere_form_factor(o, n, [0, 0, 1], 0.0) == 0.0  # no sphere
    assert sphere_form_factor(o, n, [0, 0, 1], np.nan) == 0.0
    assert sphere_form_factor(o, n, [0, 0, 1e8], 1.0) == pytest.approx(1e-16, rel=1e-9)


def cosine_directions(n: int) -> np.ndarray:
    """``n`` cosine-distributed directions about +Z: a Vogel (golden-angle) spiral filling the unit
    disk evenly, lifted to the hemisphere (Malley's method)."""
    i = np.arange(n) + 0.5
    r, phi = np.sqrt(i / n), np.pi * (3 - 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - r * r)], axis=1)


def brute_blocking(points, normals, centers, radii, directions) -> np.ndarray:
    """``(V, J)`` fraction of the cosine-distributed rays from each point that hit each sphere."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(normals, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(normals, t1)
    rays = (directions[None, :, :1] * t1[:, None] + directions[None, :, 1:2] * t2[:, None]
            + directions[None, :, 2:] * normals[:, None])  # (V, N, 3)
    out = np.zeros((len(points), len(centers)))
    for j, (c, r) in enumerate(zip(centers, radii)):
        v = c - points
        ell = np.linalg.norm(v, axis=1)
        cos_cap = np.sqrt(np.maximum(1 - (r / ell) ** 2, 0))
        hit = np.einsum("vnk,vk->vn", rays, v / ell[:, None]) >= cos_cap[:, None]
        out[:, j] = np.where(ell <= r, 1.0, hit.mean(axis=1))
    return out


@pytest.mark.parametrize("reduce", ["mean", "max"])
def test_top_k_matches_brute_force_over_keyframes(reduce):
    av = avatar_from_gltf(walker_gltf())
    sp = fit_proxy_spheres(av)
    k = 3
    got = select_blockers(av, sp, k=k, animation=0, reduce=reduce)
    assert np.array_equal(got.keyframes, KEYFRAMES)
    verts = np.arange(0, len(av.positions), 7)
    rest = rest_positions()
    dirs = cosine_directions(3000)
    per_frame = []
    for t in KEYFRAMES:
        g = walk_globals(t)
        mats = np.stack([g[b.name] @ np.block([[np.eye(3), -rest[b.name][:, None]], [np.zeros((1, 3)), 1]])
                         for b in BONES])
        blend = np.einsum("vi,vijk->vjk", av.weights[verts], mats[av.joints[verts]])
        pts = np.einsum("vjk,vk->vj", blend[:, :3, :3], av.positions[verts]) + blend[:, :3, 3]
        nrm = np.einsum("vkj,vk->vj", np.linalg.inv(blend[:, :3, :3]), av.normals[verts])
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        centers = np.stack([g[b.name][:3, :3] @ c + g[b.name][:3, 3] for b, c in zip(BONES, sp.centers)])
        per_frame.append(brute_blocking(pts, nrm, centers, sp.radii, dirs))
    ref = np.mean(per_frame, axis=0) if reduce == "mean" else np.max(per_frame, axis=0)
    own = np.zeros_like(ref, dtype=bool)
    for slot in range(4):
        own[np.arange(len(verts)), av.joints[verts, slot]] |= av.weights[verts, slot] > 0
    ref[own] = 0.0
    tol = 5e-3  # ray-count error of 3000 spiral rays (measured: <= 3.4e-3, all vertices and keyframes)
    chosen, scores = got.joints[verts], got.scores[verts]
    picked = np.take_along_axis(ref, chosen, axis=1)
    used = scores > 0
    assert np.all(np.abs(picked[used] - scores[used]) < tol), np.abs(picked[used] - scores[used]).max()
    kth = -np.sort(-ref, axis=1)[:, k - 1]
    assert np.all(picked[used] >= kth[:, None].repeat(k, 1)[used] - 2 * tol)  # a true top k, up to near-ties
    assert np.all(ref[~used.any(axis=1)].max(axis=1, initial=0) < tol)  # no blocker left out of an empty row
    top, order = -np.sort(-ref, axis=1), np.argsort(-ref, axis=1, kind="stable")
    checked = np.zeros(len(verts), dtype=bool)
    for m in range(1, k + 1):  # the top m, wherever the m-th place is clear of near-ties
        decided = (top[:, m - 1] - top[:, m] > 2 * tol) & (top[:, m - 1] > 2 * tol)
        assert np.array_equal(np.sort(chosen[decided, :m], axis=1), np.sort(order[decided, :m], axis=1)), m
        checked |= decided
    assert checked.sum() > 0.6 * len(verts)  # a non-trivial case: most vertices have a clear top m
    assert not np.any(own[np.arange(len(verts))[:, None], chosen] & used)  # own joints never chosen


def test_bad_arguments():
    av = avatar_from_gltf(walker_gltf())
    sp = fit_proxy_spheres(av)
    with pytest.raises(ValueError, match=r"k \(--k\) must be"):
        select_blockers(av, sp, k=5)
    with pytest.raises(ValueError, match=r"reduce \(--reduce\) must be"):
        select_blockers(av, sp, reduce="median")
    with pytest.raises(ValueError, match="exclude_weight"):
        select_blockers(av, sp, exclude_weight=float("nan"))
