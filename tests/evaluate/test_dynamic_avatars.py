"""Street evaluation with avatars, checked against independent references:

* a posed walker added to a scene (``with_meshes``): the scene's own vertices untouched, and a
  32^2 capture sees the mesh exactly where a float64 ray cast of the posed triangles hits it
  (distance per texel), nowhere outside the mesh's bounding box's directions;
* the crowd LOD rule: near avatars give their bone spheres, far ones one sphere;
* a small avatar ring around a point in the canyon: against a fresh 16^2 capture with the meshes,
  the dynamic terms of the proxy spheres move the Eq. 3 error toward the truth; the rows as a
  section of the evaluator's report.md (``envcap evaluate --occluders``);
* a user's avatar file (``envcap evaluate --avatar``): the walker through ``envcap avatar`` gives
  the default's rows exactly, a child-sized one hides less; the spheres are read from the file
  (edited radii come back edited); bad files are refused before any work.
"""

from __future__ import annotations

import numpy as np
import pygltflib
import pytest

from envcap.capture.renderer import CubeCapture
from envcap.cli import main
from envcap.core import cube
from envcap.dynamic.avatar_attributes import read_annotated, write_annotated
from envcap.dynamic.avatar_synthetic import walker_gltf
from envcap.evaluate.dynamic_avatars import (
    AvatarRing,
    Crowd,
    crowd_avatars,
    evaluate_avatar_crowds,
    load_rigged,
    lod_spheres,
    pose_avatar,
    walker_path,
)
from envcap.evaluate.occluder_report import append_occluder_report
from envcap.evaluate.predict import Predictor
from envcap.evaluate.shading import MATERIALS
from envcap.scene import load_scene
from envcap.scene.extra_meshes import ExtraMesh, with_meshes

X = np.array([0.0, 1.0, 0.0])   # on the canyon's center line (street along x), 1 m up


@pytest.fixture(scope="module")
def canyon():
    return load_scene("canyon")


@pytest.fixture(scope="module")
def walker():
    return load_rigged(str(walker_path()))


def ray_mesh(origin: np.ndarray, dirs: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Nearest hit distance of each ray ``(M, 3)`` on triangles ``(T, 3, 3)`` (inf: none), float64
    Moller-Trumbore, both faces."""
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(dirs[:, None, :], e2[None])
    det = np.einsum("tk,mtk->mt", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - tri[:, 0]
    u = np.einsum("tk,mtk->mt", s, p) * inv
    q = np.cross(s, e1)
    v = np.einsum("mk,tk->mt", dirs, q) * inv
    t = np.einsum("tk,tk->t", e2, q)[None] * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return np.where(hit, t, np.inf).min(axis=1)


def test_posed_avatar_appears_where_its_triangles_are(canyon, walker, gl_ctx):
    avatar, proxies = walker
    posed = pose_avatar(avatar, proxies, (1.3, 0.0, 0.0), -90.0, 0.25)   # facing -X, toward the point
    before = canyon.mesh.positions.copy()
    assert with_meshes(canyon, []) is canyon
    sc = with_meshes(canyon, [posed.mesh])
    nv = before.shape[0]
    assert np.array_equal(canyon.mesh.positions, before) and np.array_equal(sc.mesh.positions[:nv], before)
    assert sc.mesh.triangle_count == canyon.mesh.triangle_count + len(avatar.triangles)
    sky = canyon.sky.build()
    n = 32
    with CubeCapture.from_scene(canyon, n, sky=sky, ctx=gl_ctx) as cap:
        plain = cap.capture(X)
    with CubeCapture.from_scene(sc, n, sky=sky, ctx=gl_ctx) as cap:
        withs = cap.capture(X)
    u = cube.texel_directions(n)[0].reshape(-1, 3)                        # +X face
    hit = ray_mesh(X, u, posed.mesh.positions[posed.mesh.triangles]).reshape(n, n)
    inside = np.isfinite(hit)
    # interior texels (all 4 neighbours hit too): the capture's distance is the ray cast's
    core = inside.copy()
    core[1:-1, 1:-1] &= inside[:-2, 1:-1] & inside[2:, 1:-1] & inside[1:-1, :-2] & inside[1:-1, 2:]
    core[[0, -1], :] = False
    core[:, [0, -1]] = False
    assert core.sum() >= 20
    assert np.allclose(withs.distance[0][core], hit[core], rtol=0.01)
    assert np.all(withs.rgba[0][core][:, 3] == 1)
    # texels whose ray misses the mesh by more than a texel: the capture did not change there
    far = ~inside.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            far &= ~np.roll(np.roll(inside, dy, 0), dx, 1)
    assert np.array_equal(withs.rgba[0][far], plain.rgba[0][far])
    lo, hi = posed.mesh.bounds()
    assert np.all(withs.distance[0][core] >= lo[0] - X[0] - 1e-3) and np.all(withs.distance[0][core] <= 2 * hi[0])
    assert np.array_equal(withs.rgba[1], plain.rgba[1])                  # -X face: nothing changed


def test_extra_mesh_rejects_bad_input():
    tri = np.array([[0, 1, 2]])
    p = np.eye(3)
    with pytest.raises(ValueError, match="outside"):
        ExtraMesh(p, p, np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match="zero-length"):
        ExtraMesh(p, np.zeros((3, 3)), tri)
    with pytest.raises(ValueError, match="albedo"):
        ExtraMesh(p, p, tri, (2.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        ExtraMesh(np.full((3, 3), np.nan), p, tri)


def test_crowd_lod_near_bones_far_one_sphere(walker):
    avatar, proxies = walker
    crowd = Crowd((AvatarRing(3, 1.0), AvatarRing(4, 6.0)))
    avatars = crowd_avatars(crowd, X, 0.0, avatar, proxies)
    buf, near = lod_spheres(X, avatars)
    bones = int(np.sum(proxies.radii > 0))
    assert near == 3 and len(buf.radii) == 3 * bones + 4
    for a in avatars:                                                     # every bone sphere inside the mesh's box
        lo, hi = a.mesh.bounds()
        assert np.all(a.bone_centers >= lo - 1e-9) and np.all(a.bone_centers <= hi + 1e-9)
    ring = [np.linalg.norm(a.one.center[[0, 2]] - X[[0, 2]]) for a in avatars]
    assert np.allclose(ring[:3], 1.0, atol=0.3) and np.allclose(ring[3:], 6.0, atol=0.3)


def test_avatar_ring_moves_the_error_toward_the_truth(canyon, canyon_probe_set, gl_ctx, tmp_path):
    predictor = Predictor(canyon_probe_set, sky=canyon.sky.build(), ctx=gl_ctx)
    x = [canyon_probe_set.manifest.streets[0].probes[3].position[0], 1.0, 0.0]
    rows = evaluate_avatar_crowds(canyon, predictor, "main", [x], crowds=[Crowd((AvatarRing(6, 0.6),))], ctx=gl_ctx,
                                  resolution=16, materials=MATERIALS[:1], models=("envcap",))
    err = {r["variant"]: r["rel_err"] for r in rows}
    assert rows[0]["sky_hidden"] > 0.05 and rows[0]["near"] == 6 and rows[0]["spheres"] == 6 * 11
    assert err["oracle"] > 0.05
    assert err["static+envcap"] < 0.8 * err["static"] and err["oracle+envcap"] < 0.7 * err["oracle"]
    # the rows as the evaluator's report section: the table's numbers are the rows'
    (tmp_path / "report.md").write_text("# report\n")
    files = append_occluder_report(tmp_path, [{"scene": "canyon", "kind": "avatars", "resolution": 16, "ring": None,
                                               "avatars": rows, "positions": {"avatars": [x]}, "models": ["envcap"]}])
    md = (tmp_path / "report.md").read_text()
    assert md.startswith("# report\n") and "## Dynamic occluders" in md and files[1] in md
    assert f"| {100 * err['static']:.1f} | {100 * err['static+envcap']:.1f} |" in md
    assert (tmp_path / files[1]).stat().st_size > 1000
    with pytest.raises(SystemExit):
        main(["evaluate", "canyon", "--bake", "40", "--out", str(tmp_path / "r"), "--occluders", "spheres"])


# ------------------------------------------------------------------ a user's avatar file (--avatar)


def _scaled_walker(path, scale: float) -> None:
    """The walker under a root node scaled by ``scale`` (a child's size for ``scale`` < 1, feet
    still at y = 0): a user's own skinned glTF, not the bundled file."""
    g = walker_gltf()
    g.nodes.append(pygltflib.Node(name="root", scale=[scale] * 3, children=[0]))
    g.scenes[0].nodes = [len(g.nodes) - 1, g.scenes[0].nodes[1]]
    g.save_binary(str(path))


def test_an_envcap_avatar_file_is_the_crowds_avatar(canyon, canyon_probe_set, gl_ctx, tmp_path):
    """``evaluate_avatar_crowds(avatar_path=FILE)`` with a file ``envcap avatar`` wrote: the bundled
    walker through ``envcap avatar`` gives the default's rows exactly (its stored spheres are the
    fit's, every bit); a child-sized avatar (0.8 x) hides less sky and covers less with its spheres."""
    predictor = Predictor(canyon_probe_set, sky=canyon.sky.build(), ctx=gl_ctx)
    x = [canyon_probe_set.manifest.streets[0].probes[3].position[0], 1.0, 0.0]

    def rows(path=None):
        return evaluate_avatar_crowds(canyon, predictor, "main", [x], crowds=[Crowd((AvatarRing(6, 0.6),))], ctx=gl_ctx,
                                      resolution=16, materials=MATERIALS[:1], models=("envcap",), avatar_path=path)

    assert main(["avatar", str(walker_path()), "--out", str(tmp_path / "walker_envcap.glb"), "--quiet"]) == 0
    _scaled_walker(tmp_path / "child.glb", 0.8)
    assert main(["avatar", str(tmp_path / "child.glb"), "--out", str(tmp_path / "child_envcap.glb"), "--quiet"]) == 0
    default, walker, child = rows(), rows(tmp_path / "walker_envcap.glb"), rows(tmp_path / "child_envcap.glb")
    assert walker == default
    assert default[0]["sky_hidden"] > 0.05 and child[0]["sky_hidden"] < 0.5 * default[0]["sky_hidden"]
    assert child[0]["coverage"] < 0.7 * default[0]["coverage"] and child[0]["spheres"] == default[0]["spheres"]


def test_read_annotated_reads_the_stored_spheres_and_refuses_other_files(tmp_path):
    out = tmp_path / "w.glb"
    _, fitted, _ = write_annotated(walker_path(), out)
    avatar, spheres = read_annotated(out)
    np.testing.assert_array_equal(spheres.radii, fitted.radii)       # float64 round trip, every bit
    np.testing.assert_array_equal(spheres.centers, fitted.centers)
    np.testing.assert_array_equal(spheres.owner, fitted.owner)
    # the spheres come from the file, not a new fit: edited radii are read back as written
    g = pygltflib.GLTF2().load(str(out))
    g.skins[0].extras["envcap_proxy_spheres"]["radii"] = [2 * r for r in fitted.radii.tolist()]
    g.save_binary(str(tmp_path / "edited.glb"))
    np.testing.assert_allclose(read_annotated(tmp_path / "edited.glb")[1].radii, 2 * fitted.radii, rtol=0)
    g.skins[0].extras["envcap_proxy_spheres"]["radii"] = [0.1] * 3
    g.save_binary(str(tmp_path / "short.glb"))
    with pytest.raises(ValueError, match=r"short.glb: skins\[0\].extras.envcap_proxy_spheres does not fit the skin's 11 joints"):
        read_annotated(tmp_path / "short.glb")
    with pytest.raises(ValueError, match="was not written by envcap avatar"):
        read_annotated(walker_path())
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_annotated(tmp_path / "none.glb")
    assert avatar.joint_count == 11


@pytest.mark.parametrize("avatar, occluders, words", [
    ("none.glb", "avatars", "--avatar none.glb: no such file"),
    ("WALKER", "all", "was not written by envcap avatar (it has no proxy spheres); make one with: envcap avatar"),
    ("w.glb", "ring", "--avatar goes with --occluders avatars or all"),
    (".", "avatars", "--avatar . is a directory"),
])
def test_evaluate_refuses_a_bad_avatar_before_any_work(tmp_path, capsys, monkeypatch, avatar, occluders, words):
    monkeypatch.chdir(tmp_path)
    write_annotated(walker_path(), tmp_path / "w.glb")
    avatar = str(walker_path()) if avatar == "WALKER" else avatar
    code = main(["evaluate", "canyon", "--bake", "40", "--out", "report", "--occluders", occluders, "--avatar", avatar])
    err = capsys.readouterr().err
    assert code == 2 and words in err and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.glb"]      # nothing written
