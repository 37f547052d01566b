"""The crowd's per-frame data: nearest neighbours against a brute-force sort, the LOD of the sphere
gather (bone spheres near, one sphere far), and the instance texture's joint matrices skinning a
vertex as envcap.dynamic.gltf_skin.skin does."""

import numpy as np

from envcap.crowd.inputs import default_avatar
from envcap.crowd.instances import AvatarCycle, instance_texture, pose_crowd
from envcap.crowd.sphere_buffer import fragment_spheres, nearest_neighbours, neighbour_texture
from envcap.crowd.walkers import place_walkers
from envcap.dynamic.crowd_lod import NEAR_FACTOR
from envcap.dynamic.gltf_skin import joint_matrices, skin
from envcap.runtime.street import StreetProbes
from terrain_manifest import terrain_manifest


def test_nearest_neighbours_are_the_brute_force_ones():
    rng = np.random.default_rng(1)
    for n in (1, 2, 7, 700):
        one = np.c_[rng.uniform(-50, 50, (n, 3)), np.ones((n, 2))]
        got = nearest_neighbours(one, 6)
        d = np.linalg.norm(one[:, None, :3] - one[None, :, :3], axis=2)
        np.fill_diagonal(d, np.inf)
        want = np.argsort(d, axis=1, kind="stable")[:, :min(6, n - 1)]
        assert np.array_equal(got[:, :want.shape[1]], want)
        assert np.all(got[:, want.shape[1]:] == -1)


def _crowd(n=5):
    av = default_avatar()
    st = StreetProbes.from_manifest(terrain_manifest((3.0, 3.4), (0.08, 0.06), 35.0).streets[0])
    wk = place_walkers(st, n, seed=2)
    cycle = AvatarCycle.of(av.avatar, av.spheres)
    return av, wk, cycle, pose_crowd(wk, cycle, 0.37, np.array([10.0, 3.0, 20.0]))


def test_the_gather_takes_bone_spheres_near_and_one_sphere_far():
    av, wk, cycle, pose = _crowd()
    nb = nearest_neighbours(pose.one)
    m = nb[0, 0]
    j = av.avatar.joint_count
    near = pose.one[m, :3] + [0.0, 0.0, 0.5]                  # half a metre from neighbour m's centre
    sph = fragment_spheres(near, 0, np.zeros((2, 4)), pose, nb[:, :1], use_self=False, use_neighbours=True, albedo=0.4)
    assert len(sph) == j and np.allclose(sph.centers, pose.spheres[m, :, :3])
    far = pose.one[m, :3] + [0.0, 0.0, NEAR_FACTOR * pose.one[m, 4] + 0.01]
    sph = fragment_spheres(far, 0, np.zeros((2, 4)), pose, nb[:, :1], use_self=False, use_neighbours=True, albedo=0.4)
    assert len(sph) == 1 and np.allclose(sph.centers[0], pose.one[m, :3]) and sph.radii[0] == pose.one[m, 3]
    selfs = np.array([[1.0, 2.0, 3.0, 0.1], [0.0, 0.0, 0.0, 0.0]])     # an empty second slot is left out
    sph = fragment_spheres(far, 0, selfs, pose, nb, use_self=True, use_neighbours=False, albedo=0.4)
    assert len(sph) == 1 and np.allclose(sph.centers[0], [1, 2, 3])
    tex = neighbour_texture(pose, nb)
    assert np.allclose(tex[0, 0], pose.one[m, :4]) and tex[0, 6, 1] == m and tex[0, 6, 0] == np.float32(pose.one[m, 4])


def test_instance_texture_joint_matrices_skin_like_gltf_skin():
    av, wk, cycle, pose = _crowd()
    tex = instance_texture(pose)
    j = av.avatar.joint_count
    assert tex.shape == (len(wk), 6 * j, 4)
    i = 3
    mats = np.stack([tex[i, 4 * k:4 * k + 4].T for k in range(j)]).astype(np.float64)   # texels are columns
    p, _ = skin(mats, av.avatar)
    t = cycle.times[pose.samples[i]]
    p_ref, _ = skin(joint_matrices(av.avatar, 0, float(t)), av.avatar)
    p_ref = p_ref @ pose.roots[i, :3, :3].T + pose.roots[i, :3, 3]
    assert np.allclose(p, p_ref, atol=1e-4)
    assert np.allclose(tex[i, 4 * j:5 * j], pose.spheres[i], atol=1e-5)


def test_the_estimate_grows_with_walkers_and_size_and_a_huge_crowd_is_refused(monkeypatch):
    from envcap.core.budget import BudgetError, check_bytes
    from envcap.crowd.run import estimate_bytes

    small = estimate_bytes((64, 48), 10, 11, 982, 1000, 10**6)
    assert estimate_bytes((64, 48), 1000, 11, 982, 1000, 10**6) > small + 1000 * 11 * 6 * 16
    assert estimate_bytes((1680, 1050), 10, 11, 982, 1000, 10**6) > small + 1680 * 1050 * 16
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "1G")
    import pytest
    with pytest.raises(BudgetError):
        check_bytes("crowd", estimate_bytes((8192, 8192), 10**6, 11, 982, 1000, 10**6), "--avatars")
