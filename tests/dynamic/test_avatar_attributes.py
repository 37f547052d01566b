"""The annotated avatar file (issue 14, Sections V-VI): vertex attributes and extras read back with
pygltflib, ``envcap avatar`` output safety, and the crowd LOD sphere and its distance rule."""

from __future__ import annotations

import math

import numpy as np
import pygltflib
import pytest
from test_avatar_blockers import cosine_directions

from envcap.cli import main
from envcap.dynamic.avatar_attributes import BLOCKER_WEIGHTS_ATTRIBUTE, BLOCKERS_ATTRIBUTE, is_envcap_avatar, write_annotated
from envcap.dynamic.avatar_blockers import select_blockers, sphere_form_factor
from envcap.dynamic.avatar_synthetic import walker_gltf
from envcap.dynamic.crowd_lod import NEAR_FACTOR, avatar_sphere, crowd_spheres, union_disk_area, use_bone_spheres
from envcap.dynamic.gltf_buffers import read_accessor
from envcap.dynamic.gltf_skin import avatar_from_gltf, load_avatar
from envcap.dynamic.proxy_spheres import fit_proxy_spheres, pose_spheres


@pytest.fixture(scope="module")
def walker_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("annotate") / "walker.glb"
    walker_gltf().save_binary(str(path))
    return path


def test_attributes_and_extras_round_trip(walker_file, tmp_path):
    out = tmp_path / "walker_envcap.glb"
    before = walker_file.read_bytes()
    av, sp, bl = write_annotated(walker_file, out, k=2, reduce="max")
    assert walker_file.read_bytes() == before  # the input is untouched
    g = pygltflib.GLTF2().load(str(out))
    attrs = g.meshes[0].primitives[0].attributes
    joints, weights = read_accessor(g, getattr(attrs, BLOCKERS_ATTRIBUTE)), read_accessor(g, getattr(attrs, BLOCKER_WEIGHTS_ATTRIBUTE))
    assert g.accessors[getattr(attrs, BLOCKERS_ATTRIBUTE)].componentType == pygltflib.UNSIGNED_BYTE
    assert joints.shape == weights.shape == (len(av.positions), 4)
    np.testing.assert_array_equal(joints[:, 2:], 0)
    np.testing.assert_array_equal(weights[:, 2:], 0)
    # what was written is an independent recomputation from the original file
    want = select_blockers(load_avatar(walker_file), fit_proxy_spheres(load_avatar(walker_file)), k=2, reduce="max")
    np.testing.assert_array_equal(joints[:, :2], want.joints)
    np.testing.assert_allclose(weights[:, :2], want.scores, rtol=1e-6)
    ext = g.skins[0].extras["envcap_proxy_spheres"]
    np.testing.assert_allclose(ext["radii"], sp.radii, atol=1e-6)
    lod = g.animations[0].extras["envcap_avatar_sphere"]
    assert lod["times"] == [0.0, 0.25, 0.5, 0.75, 1.0] and lod["near_factor"] == NEAR_FACTOR
    one = avatar_sphere(*pose_spheres(sp, av, 0, 0.25))
    assert lod["radii"][1] == pytest.approx(one.radius, abs=1e-6)
    # the rest of the file survives: the skinned mesh reads back the same
    again = load_avatar(out)
    np.testing.assert_array_equal(again.positions, av.positions)
    np.testing.assert_array_equal(again.joints, av.joints)
    assert is_envcap_avatar(out) and not is_envcap_avatar(walker_file)
    with pytest.raises(ValueError, match="already has _ENVCAP_BLOCKERS"):
        write_annotated(out, tmp_path / "twice.glb")


def test_cli_writes_and_guards(walker_file, tmp_path, capsys):
    out = tmp_path / "o" / "w.glb"
    assert main(["avatar", str(walker_file), "--out", str(out)]) == 0
    assert "11 joints" in capsys.readouterr().out and is_envcap_avatar(out)
    assert main(["avatar", str(walker_file), "--out", str(out), "--k", "1"]) == 0  # replaces its own output
    assert main(["avatar", str(walker_file), "--out", str(walker_file), "--force"]) == 2
    assert "is the input" in capsys.readouterr().err
    foreign = tmp_path / "mine.glb"
    foreign.write_bytes(b"not envcap's")
    assert main(["avatar", str(walker_file), "--out", str(foreign)]) == 2
    assert "not written by envcap" in capsys.readouterr().err and foreign.read_bytes() == b"not envcap's"
    assert main(["avatar", str(walker_file), "--out", str(tmp_path / "x.glb"), "--k", "9"]) == 2
    assert "k (--k) must be" in capsys.readouterr().err and not (tmp_path / "x.glb").exists()
    assert main(["avatar", str(tmp_path / "missing.glb"), "--out", str(tmp_path / "y.glb")]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.glb", "o"]  # nothing half-written


def test_avatar_sphere_hand_cases():
    lens = 2 * math.acos(0.5) - 0.5 * math.sqrt(3)  # two unit disks 1 apart overlap by this much
    assert union_disk_area(np.array([[0.0, 0], [1, 0]]), np.ones(2)) == pytest.approx(2 * math.pi - lens, abs=1e-12)
    assert union_disk_area(np.array([[0.0, 0], [0, 0]]), np.ones(2)) == pytest.approx(math.pi, abs=1e-12)
    assert union_disk_area(np.array([[0.0, 0], [3, 0]]), np.array([1.0, 2.0])) == pytest.approx(5 * math.pi, abs=1e-12)
    one = avatar_sphere([[1.0, 2.0, 3.0]], [0.5])
    np.testing.assert_allclose(one.center, [1, 2, 3])
    assert one.radius == pytest.approx(0.5, abs=1e-12) and one.enclosing == 0.5
    nested = avatar_sphere([[0.0, 0, 0], [0.1, 0, 0]], [1.0, 0.3])  # the union is the big sphere
    assert nested.radius == pytest.approx(1.0, abs=1e-12)
    far = avatar_sphere([[-5.0, 0, 0], [5.0, 0, 0]], [1.0, 1.0])  # disjoint unless seen nearly end-on
    assert math.sqrt(1.9) < far.radius <= math.sqrt(2.0) + 1e-12 and far.enclosing == pytest.approx(6.0)
    with pytest.raises(ValueError, match="no sphere of positive radius"):
        avatar_sphere([[0.0, 0, 0]], [0.0])
    with pytest.raises(ValueError, match="finite"):
        avatar_sphere([[np.nan, 0, 0]], [1.0])


def test_lod_rule_error_at_the_threshold():
    """Beyond NEAR_FACTOR enclosing radii, the one sphere's form factor is within 0.005 of the
    union of the bone spheres (rays), normal facing the avatar: the documented rule."""
    av = avatar_from_gltf(walker_gltf())
    centers, radii = pose_spheres(fit_proxy_spheres(av), av, 0, 0.25)
    one = avatar_sphere(centers, radii)
    dirs = cosine_directions(6000)
    worst = 0.0
    for az in np.linspace(0, 2 * np.pi, 6, endpoint=False):
        out = np.array([math.cos(az), 0.0, math.sin(az)])
        p, n = one.center + 1.001 * NEAR_FACTOR * one.enclosing * out, -out
        t1 = np.cross(n, [0.0, 1.0, 0.0])
        t1 /= np.linalg.norm(t1)
        rays = dirs[:, :1] * t1 + dirs[:, 1:2] * np.cross(n, t1) + dirs[:, 2:] * n
        v = centers - p
        ell = np.linalg.norm(v, axis=1)
        hit = (rays @ (v / ell[:, None]).T >= np.sqrt(1 - (radii / ell) ** 2)).any(axis=1)
        worst = max(worst, abs(float(sphere_form_factor(p, n, one.center, one.radius)) - hit.mean()))
        assert not use_bone_spheres(p, one) and use_bone_spheres(one.center + 0.99 * (p - one.center), one)
    assert worst < 0.005
    c, r = crowd_spheres(one.center + [0.5, 0, 0], [(centers, radii), (centers + [50, 0, 0], radii)],
                         [one, avatar_sphere(centers + [50, 0, 0], radii)])
    assert len(c) == len(centers) + 1 and r[-1] == pytest.approx(one.radius)
