"""Skinned glTF avatars (issue 14, Section V): the test avatar is read back with pygltflib and posed
exactly as its closed-form walk says; proxy spheres follow their rule; bad files fail clearly."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from envcap.core.resources import city_scenes_dir
from envcap.dynamic.avatar_synthetic import BONES, KEYFRAMES, capsule, rest_positions, walk_hips_height, walk_rotation, walker_gltf
from envcap.dynamic.gltf_buffers import GltfError
from envcap.dynamic.gltf_skin import NodeChannel, avatar_from_gltf, sample_channel, global_matrices, joint_matrices, load_avatar, skin
from envcap.dynamic.proxy_spheres import fit_proxy_spheres, hull_sphere, pose_spheres


def rot(axis: str, a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    m = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def walk_globals(time: float) -> dict[str, np.ndarray]:
    """Reference joint transforms of the walk at ``time``: closed-form angles at the keyframes,
    linear in the angle between them (what slerp of rotations about one axis gives)."""
    k = min(int(np.searchsorted(KEYFRAMES, time, side="right")) - 1, len(KEYFRAMES) - 2)
    t0, t1 = KEYFRAMES[k], KEYFRAMES[k + 1]
    u = (time - t0) / (t1 - t0)
    out: dict[str, np.ndarray] = {}
    for bone in BONES:
        ax, a0 = walk_rotation(bone.name, t0)
        a = (1 - u) * a0 + u * walk_rotation(bone.name, t1)[1]
        tr = np.eye(4)
        tr[:3, 3] = bone.offset
        if bone.parent is None:
            tr[1, 3] = (1 - u) * walk_hips_height(t0) + u * walk_hips_height(t1)
        out[bone.name] = (out[bone.parent] if bone.parent else np.eye(4)) @ tr @ rot(ax, a)
    return out


@pytest.fixture(scope="module")
def walker_path(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("avatar") / "walker.glb"
    walker_gltf().save_binary(str(path))
    return path


def test_bundled_walker_is_the_generator_output(walker_path):
    bundled = city_scenes_dir() / "avatars" / "walker.glb"
    assert bundled.read_bytes() == walker_path.read_bytes(), "rerun city_scenes/avatars/make_walker.py"
    assert bundled.stat().st_size < 200_000


def test_pose_matches_the_closed_form_walk(walker_path):
    av = load_avatar(walker_path)
    assert av.joint_names == tuple(b.name for b in BONES) and av.weights.shape == (len(av.positions), 4)
    assert np.allclose(av.weights.sum(axis=1), 1.0) and (av.weights[:, 1] > 0).sum() > 50  # blended vertices
    np.testing.assert_allclose(joint_matrices(av), np.broadcast_to(np.eye(4), (11, 4, 4)), atol=1e-6)  # bind pose
    rest = rest_positions()
    for time in (*KEYFRAMES, 0.1, 0.6, 0.93):
        ref = walk_globals(time)
        got = global_matrices(av, 0, time)[av.joint_nodes]
        np.testing.assert_allclose(got, np.stack([ref[b.name] for b in BONES]), atol=2e-6)
        pts, nrm = skin(joint_matrices(av, 0, time), av)
        # independent linear blend skinning with the reference matrices (rest pose = bind pose)
        mats = np.stack([ref[b.name] @ np.block([[np.eye(3), -rest[b.name][:, None]], [np.zeros((1, 3)), 1]])
                         for b in BONES])
        blend = np.einsum("vi,vijk->vjk", av.weights, mats[av.joints])
        want = np.einsum("vjk,vk->vj", blend[:, :3, :3], av.positions) + blend[:, :3, 3]
        np.testing.assert_allclose(pts, want, atol=5e-6)
        rigid = av.weights[:, 0] == 1
        np.testing.assert_allclose(nrm[rigid], np.einsum("vjk,vk->vj", mats[av.joints[rigid, 0], :3, :3],
                                                         av.normals[rigid]), atol=1e-5)


def test_sampling_clamps_steps_and_splines(walker_path):
    times, vals = np.array([0.0, 2.0]), np.array([[0.0, 0, 0], [4.0, 2, 0]])
    assert np.array_equal(sample_channel(NodeChannel(0, "translation", times, vals, "STEP"), 1.9), [0, 0, 0])
    np.testing.assert_allclose(sample_channel(NodeChannel(0, "translation", times, vals, "LINEAR"), 0.5), [1, 0.5, 0])
    # CUBICSPLINE (in-tangent, value, out-tangent): zero tangents -> Hermite h00 = h01 = 1/2 at u = 1/2;
    # unit out-tangent at the start adds dt * h10(1/2) = 2 / 8
    cubic = np.array([[0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 0, 0], [4, 2, 0], [0, 0, 0]], dtype=float)
    np.testing.assert_allclose(sample_channel(NodeChannel(0, "translation", times, cubic, "CUBICSPLINE"), 1.0),
                               [2.25, 1, 0])
    av = load_avatar(walker_path)
    np.testing.assert_allclose(global_matrices(av, 0, -5.0), global_matrices(av, 0, 0.0))
    np.testing.assert_allclose(global_matrices(av, 0, 7.0), global_matrices(av, 0, 1.0))
    with pytest.raises(ValueError, match="animation 3 does not exist"):
        global_matrices(av, 3, 0.0)


def test_hull_sphere_rule():
    # a fine sphere: centre and radius back (inscribed polyhedron: area slightly under 4 pi r^2)
    p, _, _ = capsule(np.zeros(3), np.zeros(3), 0.5, around=64, cap_rings=32)
    c, r = hull_sphere(p + [1.0, 2.0, 3.0])
    np.testing.assert_allclose(c, [1, 2, 3], atol=1e-9)
    assert 0.5 * 0.995 < r < 0.5
    # a capsule of length L, radius a: sqrt(a (a + L / 2)) (equal mean projected area, Cauchy)
    p, _, _ = capsule(np.zeros(3), np.array([0, 0.4, 0]), 0.06, around=64, cap_rings=32, body_rings=8)
    c, r = hull_sphere(p)
    np.testing.assert_allclose(c, [0, 0.2, 0], atol=1e-9)
    assert abs(r / math.sqrt(0.06 * (0.06 + 0.2)) - 1) < 0.005
    assert hull_sphere(p[:3])[1] == 0.0  # too few points
    flat = np.c_[np.random.default_rng(0).random((20, 2)), np.zeros(20)]
    assert hull_sphere(flat)[1] == 0.0  # a flat hull


def test_proxy_spheres_move_with_their_bones(walker_path):
    av = load_avatar(walker_path)
    sp = fit_proxy_spheres(av)
    assert np.all(sp.radii > 0) and sp.vertex_counts.sum() == len(av.positions)
    for time in (0.25, 0.6):
        centers, radii = pose_spheres(sp, av, 0, time)
        pts, _ = skin(joint_matrices(av, 0, time), av)
        for j in range(av.joint_count):
            # rigid vertices of joint j keep their distance to its sphere's centre
            rigid = (av.joints[:, 0] == j) & (av.weights[:, 0] == 1)
            rest_d = np.linalg.norm(av.positions[rigid] - pose_spheres(sp, av, None)[0][j], axis=1)
            np.testing.assert_allclose(np.linalg.norm(pts[rigid] - centers[j], axis=1), rest_d, atol=1e-5)
        np.testing.assert_allclose(radii, sp.radii)


def test_bad_files_fail_clearly(tmp_path, walker_path):
    junk = tmp_path / "junk.glb"
    junk.write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(GltfError, match="not a readable glTF"):
        load_avatar(junk)
    split = walker_gltf()  # a .gltf with its buffer in a .bin beside it reads the same; without the .bin, an error
    (tmp_path / "walker.bin").write_bytes(split.binary_blob())
    split.buffers[0].uri = "walker.bin"
    (tmp_path / "walker.gltf").write_text(split.to_json())
    np.testing.assert_array_equal(load_avatar(tmp_path / "walker.gltf").positions, load_avatar(walker_path).positions)
    (tmp_path / "walker.bin").unlink()
    with pytest.raises(GltfError, match="buffer is missing"):
        load_avatar(tmp_path / "walker.gltf")
    gltf = pygltflib.GLTF2().load(str(walker_path))
    gltf.nodes[-1].skin = None
    with pytest.raises(GltfError, match="no node has both a mesh and a skin"):
        avatar_from_gltf(gltf)
    gltf = pygltflib.GLTF2().load(str(walker_path))
    gltf.accessors[gltf.meshes[0].primitives[0].attributes.POSITION].count = 10**6
    with pytest.raises(GltfError, match="reads past"):
        avatar_from_gltf(gltf)
    gltf = pygltflib.GLTF2().load(str(walker_path))
    gltf.nodes[3].children = [0]
    with pytest.raises(GltfError, match="two parents|cycle"):
        avatar_from_gltf(gltf)
