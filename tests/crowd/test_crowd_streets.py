"""Walkers on any street: a street at an angle on sloped terrain (the manifest's grounds and slopes,
checked against the ground worked out by hand), and a crowd drawn on a turned street, the walkers
where they were placed."""

import dataclasses
import math

import numpy as np
import pytest

from envcap.core.street_frame import world_to_frame
from envcap.crowd.camera import Camera
from envcap.crowd.inputs import ALBEDO, material
from envcap.crowd.instances import AvatarCycle, pose_crowd
from envcap.crowd.sphere_buffer import nearest_neighbours
from envcap.crowd.twin import CrowdTwin
from envcap.crowd.run import CrowdJob
from envcap.crowd.walkers import SIDEWALK, place_walkers
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.store import write_probe_set
from envcap.runtime.street import StreetProbes
from envcap.scene import load_scene
from envcap.scene.segment import street_segment
from terrain_manifest import ORIGIN, along_unit, hand_ground, terrain_manifest

GROUNDS, SLOPES, YAW = (3.0, 3.4), (0.08, 0.06), 35.0


def test_walkers_stand_on_a_turned_sloped_street_and_walk_along_it():
    st = StreetProbes.from_manifest(terrain_manifest(GROUNDS, SLOPES, YAW).streets[0])
    wk = place_walkers(st, 20, seed=7)
    for t in (0.0, 0.7):
        feet = wk.positions(t)
        for x in feet:
            assert x[1] == pytest.approx(hand_ground(x, GROUNDS, SLOPES, YAW), abs=1e-9)
        f = world_to_frame(feet, YAW, ORIGIN)
        planes = st.planes[wk.nearest_probe(f[:, 0])]
        inside = np.where(wk.side < 0, f[:, 2] - planes[:, 0], planes[:, 1] - f[:, 2])
        assert np.all((inside >= SIDEWALK[0] - 1e-9) & (inside <= SIDEWALK[1] + 1e-9))
    step = wk.positions(0.5) - wk.positions(0.0)
    along = step[:, [0, 2]] @ along_unit(YAW)
    length = wk.span[1] - wk.span[0]                   # a walker past an end comes back at the other
    miss = (along - 0.5 * wk.speed * wk.direction + length / 2) % length - length / 2
    assert np.allclose(miss, 0.0, atol=1e-9)
    head = wk.headings()
    fwd = np.stack([np.sin(head), np.cos(head)], axis=1)
    assert np.allclose(fwd @ along_unit(YAW), wk.direction)   # the avatar's +Z turned onto its walk
    assert set(wk.side) == {-1, 1} and set(wk.direction) == {-1, 1}


def _turned(scene, yaw):
    a = math.radians(yaw)
    T = np.array([[math.cos(a), 0.0, math.sin(a)], [0.0, 1.0, 0.0], [-math.sin(a), 0.0, math.cos(a)]])
    m = scene.mesh
    mesh = dataclasses.replace(m, positions=(m.positions.astype(np.float64) @ T).astype(np.float32),
                               normals=(m.normals.astype(np.float64) @ T).astype(np.float32), origin=m.origin @ T)
    p = scene.sky.params
    sky = dataclasses.replace(scene.sky, params=dataclasses.replace(p, sun_azimuth_deg=p.sun_azimuth_deg - yaw))
    return dataclasses.replace(scene, mesh=mesh, sky=sky, streets=[dataclasses.replace(s, yaw_deg=yaw) for s in scene.streets])


@pytest.mark.slow
def test_a_crowd_on_a_turned_street_is_drawn_where_it_walks(gl_ctx, tmp_path):
    scene = _turned(street_segment(load_scene("canyon"), 30.0), YAW)
    write_probe_set(tmp_path / "p", bake_probe_set(scene, resolution=8, spacing=10.0, ctx=gl_ctx, progress=False))
    job = CrowdJob.prepare("turned", tmp_path / "p", 6, size=(80, 60), seed=1, scene_obj=scene)
    assert job.walkers.street.yaw_deg == YAW
    r = job.renderer(gl_ctx)
    try:
        pose = pose_crowd(job.walkers, AvatarCycle.of(job.avatar.avatar, job.avatar.spheres), 0.0, r.origin)
        on = job.walkers.on_street(np.array(job.walkers.span), np.zeros(2, np.int64), np.zeros(2)) - r.origin
        cam = Camera(on[0] + [0.0, 2.0, 0.0] - 0.1 * (on[1] - on[0]), (on[0] + on[1]) / 2 + [0.0, 1.0, 0.0], 80 / 60)
        color = r.render(pose, cam)["color"]
        bare = r.render(dataclasses.replace(pose, roots=pose.roots[:0]), cam)["color"]
        assert np.all(np.isfinite(color)) and color.std() > 0
        px, front = cam.project(pose.feet - r.origin + [0.0, 1.0, 0.0], 80, 60)
        seen = 0
        for (col, row), ok in zip(px, front):
            if ok and 1 <= col < 79 and 1 <= row < 59:
                c, rr = int(col), int(row)
                assert np.abs(color[rr - 1:rr + 2, c - 1:c + 2] - bare[rr - 1:rr + 2, c - 1:c + 2]).max() > 0
                seen += 1
        assert seen >= 3
        # the terms on the turned street equal the twin (the frame rotation into the street's frame)
        r.release()
        r = job.renderer(gl_ctx, targets=True)
        out = r.render(pose, cam)
        rows, cols = np.nonzero(out["normal"][..., 3] == 1.0)
        assert len(rows) >= 8
        twin = CrowdTwin(job.probes, job.walkers.street.runtime_street(job.method.planes), job.method, material(),
                         r.origin, ALBEDO)
        nb = nearest_neighbours(pose.one)
        for i in np.random.default_rng(1).choice(len(rows), size=min(8, len(rows)), replace=False):
            y, x = rows[i], cols[i]
            pos = out["position"][y, x]
            t = twin.terms(pos[:3], out["normal"][y, x, :3], cam.eye, int(round(pos[3])),
                           np.stack([out["self0"][y, x], out["self1"][y, x]]), pose, nb)
            scale = np.abs(t.eq3).max()
            assert np.abs(out["eq3"][y, x, :3] - t.eq3).max() < 2e-3 * scale
            assert np.abs(out["all_term"][y, x, :3] - t.all_term).max() < 2e-3 * scale
    finally:
        r.release()
