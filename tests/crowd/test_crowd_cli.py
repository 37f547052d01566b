"""``envcap crowd``: the command as typed writes tone-mapped frames and crowd.json, reproducibly
for a seed; the walkers are drawn where they were placed; bad input is one line, exit 2, nothing
written."""

import json

import numpy as np
import pytest
from PIL import Image

from envcap.cli import main
from envcap.crowd.instances import AvatarCycle, pose_crowd
from envcap.crowd.run import CrowdJob
from envcap.core.resources import city_scenes_dir


def _crowd(tmp_path, probes, out, *extra):
    return main(["crowd", "canyon", "--probes", str(probes), "--avatars", "8", "--size", "64x48",
                 "--out", str(out), *extra])


def test_crowd_as_typed_writes_frames_and_the_description(canyon_probe_dir, tmp_path, capsys):
    out = tmp_path / "crowd"
    assert _crowd(tmp_path, canyon_probe_dir, out, "--frames", "2") == 0
    frames = [np.asarray(Image.open(out / f"frame_{i:04d}.png")) for i in range(2)]
    assert all(f.shape == (48, 64, 3) for f in frames)
    assert all(f.std() > 5 for f in frames)                   # not blank
    desc = json.loads((out / "crowd.json").read_text())
    assert desc["seed"] == 0 and desc["avatars"] == 8 and desc["terms"] == "neighbours"
    feet = np.array(desc["feet_m"])
    assert feet.shape == (2, 8, 3)
    assert np.all(np.abs(feet[1] - feet[0])[:, 0] > 0.05)     # they walk (the canyon runs along x)
    assert np.all(np.abs(feet[..., 1]) < 0.01)                # on the canyon's ground, y = 0
    assert "frame 2/2" in capsys.readouterr().err             # progress on stderr


def test_the_same_seed_gives_the_same_frames_another_seed_another_crowd(canyon_probe_dir, tmp_path):
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for out, seed in ((a, "3"), (b, "3"), (c, "4")):
        assert _crowd(tmp_path, canyon_probe_dir, out, "--seed", seed) == 0
    assert (a / "frame_0000.png").read_bytes() == (b / "frame_0000.png").read_bytes()
    feet = [json.loads((d / "crowd.json").read_text())["feet_m"] for d in (a, b, c)]
    assert feet[0] == feet[1] and feet[0] != feet[2]


@pytest.mark.parametrize("args, says", [
    (["--avatars", "-1"], "--avatars must be >= 0"),
    (["--avatars", "2", "--probes", "nowhere"], "nowhere"),
    (["--avatars", "2", "--avatar", str(city_scenes_dir() / "avatars/walker.glb")], "not written by envcap avatar"),
    (["--avatars", "2", "--size", "64by48"], "--size"),
    (["--avatars", "2", "--method", "depth_refine"], "--method"),
    (["--avatars", "2", "--frames", "0"], "--frames"),
])
def test_bad_arguments_are_one_line_and_exit_2_writing_nothing(canyon_probe_dir, tmp_path, capsys, args, says):
    out = tmp_path / "out"
    probes = str(tmp_path / args[args.index("--probes") + 1]) if "--probes" in args else str(canyon_probe_dir)
    rest = [a for i, a in enumerate(args) if "--probes" not in args[max(i - 1, 0):i + 1]]
    assert main(["crowd", "canyon", "--probes", probes, "--out", str(out), *rest]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("envcap: error:") and says in err[0], err
    assert not out.exists()


def test_a_crowd_past_the_memory_limit_is_refused_before_any_work(canyon_probe_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "1G")          # the scene fits; 8000^2 float frames do not
    assert _crowd(tmp_path, canyon_probe_dir, tmp_path / "out", "--size", "8000x8000") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "memory limit" in err[0] and "--avatars or --size" in err[0]
    assert not (tmp_path / "out").exists()


def test_walkers_appear_where_they_were_placed(canyon_probe_dir, gl_ctx):
    job = CrowdJob.prepare("canyon", canyon_probe_dir, 8, size=(96, 64), seed=2)
    empty = CrowdJob.prepare("canyon", canyon_probe_dir, 0, size=(96, 64), seed=2)
    r, r0 = job.renderer(gl_ctx), empty.renderer(gl_ctx)
    try:
        cycle = AvatarCycle.of(job.avatar.avatar, job.avatar.spheres)
        pose = pose_crowd(job.walkers, cycle, 0.0, r.origin)
        cam = job.camera(r.origin)                              # the same camera for both (same span)
        with_crowd = r.render(pose, cam)["color"]
        without = r0.render(pose_crowd(empty.walkers, cycle, 0.0, r0.origin), cam)["color"]
        # the walkers' hips, projected with the camera in numpy
        hips = pose.feet - r.origin + [0.0, 1.0, 0.0]
        px, front = cam.project(hips, 96, 64)
        dist = np.linalg.norm(hips - cam.eye, axis=1)
        seen = 0
        for (col, row), ok, d in zip(px, front, dist):
            if not ok or not (2 <= col < 94 and 2 <= row < 62) or d > 25:
                continue
            c, rr = int(col), int(row)
            diff = np.abs(with_crowd[rr - 1:rr + 2, c - 1:c + 2] - without[rr - 1:rr + 2, c - 1:c + 2]).max()
            assert diff > 1e-3 * without.mean(), (col, row, d)
            seen += 1
        assert seen >= 2
        # and away from every walker the frames agree (the crowd is drawn nowhere else)
        far = np.ones(with_crowd.shape[:2], bool)
        for (col, row), ok in zip(px, front):
            if ok:
                far[max(int(row) - 30, 0):int(row) + 30, max(int(col) - 12, 0):int(col) + 12] = False
        assert far.any() and np.allclose(with_crowd[far], without[far])
    finally:
        r.release()
        r0.release()


def test_an_avatar_written_by_envcap_avatar_draws_as_the_bundled_default(canyon_probe_dir, tmp_path):
    glb = tmp_path / "walker_envcap.glb"
    assert main(["avatar", str(city_scenes_dir() / "avatars/walker.glb"), "--out", str(glb), "--quiet"]) == 0
    assert _crowd(tmp_path, canyon_probe_dir, tmp_path / "a", "--avatar", str(glb)) == 0
    assert _crowd(tmp_path, canyon_probe_dir, tmp_path / "b") == 0     # the same walker, annotated in memory
    assert (tmp_path / "a" / "frame_0000.png").read_bytes() == (tmp_path / "b" / "frame_0000.png").read_bytes()
    assert json.loads((tmp_path / "a" / "crowd.json").read_text())["avatar"] == str(glb)
