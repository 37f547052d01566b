"""``envcap avatar`` on many bones (issue 20, item 3): the blocking work runs in blocks of vertices
(bounded memory, the same result), the memory and time are estimated from the file's JSON before
any buffer is decoded (refused past the memory limit, printed first when long), and a run removes
what a killed run on the same output left (its lock and temporary file, only envcap's names)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from envcap.dynamic.avatar_blockers import select_blockers, top_k
from envcap.dynamic.avatar_cost import AvatarCounts, estimate_avatar, read_counts
from envcap.dynamic.avatar_synthetic import many_bone_gltf, walker_gltf
from envcap.dynamic.crowd_lod import union_disk_area
from envcap.dynamic.gltf_skin import avatar_from_gltf, load_avatar
from envcap.dynamic.proxy_spheres import fit_proxy_spheres, joint_weight_matrix, owner_joints

REPO = Path(__file__).resolve().parents[2]


def _envcap(*args: object, env: dict[str, str] | None = None, **kw) -> subprocess.Popen | subprocess.CompletedProcess:
    full = dict(os.environ, PYOPENGL_PLATFORM="egl", **(env or {}))
    full["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    cmd = [sys.executable, "-m", "envcap", *map(str, args)]
    if kw.pop("background", False):
        return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=full, **kw)
    return subprocess.run(cmd, capture_output=True, text=True, env=full, timeout=120, **kw)


@pytest.fixture(scope="module")
def many_bones():
    """100 joints, 9,108 vertices, 5 keyframes: the work of the old code was K x V x J float64
    (36 MB) plus the temporaries of one frame (~20 x 7 MB)."""
    return avatar_from_gltf(many_bone_gltf(100))


def test_blocks_bound_the_memory_and_do_not_change_the_result(many_bones):
    av = many_bones
    spheres = fit_proxy_spheres(av)
    frames = 8.0 * 5 * len(av.positions) * av.joint_count
    tracemalloc.start()
    try:
        got = select_blockers(av, spheres)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 24 * 2**20 < frames          # measured 12 MiB: one block, not K x V x J (34.7 MiB)
    small = select_blockers(av, spheres, pairs=17_000)   # blocks of 170 vertices, the last one shorter
    whole = select_blockers(av, spheres, pairs=10**9, keep_frames=True)   # all at once, every F kept
    for other in (small, whole):
        assert np.array_equal(other.joints, got.joints) and np.array_equal(other.scores, got.scores)
    assert got.per_frame is None and whole.per_frame.shape == (5, len(av.positions), av.joint_count)
    mean = whole.per_frame.mean(axis=0)
    rows = np.arange(len(av.positions))[:, None]
    assert np.array_equal(mean[rows, got.joints][got.scores > 0], got.scores[got.scores > 0])


def test_owner_and_top_k_equal_their_dense_forms():
    rng = np.random.default_rng(20)
    for _ in range(50):   # repeated slots, zero weights, ties
        v, j = int(rng.integers(1, 40)), int(rng.integers(1, 9))
        joints = rng.integers(0, j, (v, 4))
        weights = rng.choice([0.0, 0.25, 0.5, 1.0, rng.uniform()], (v, 4))
        weights[weights.sum(axis=1) == 0, 0] = 1.0
        av = type("A", (), {"joints": joints, "weights": weights, "positions": np.zeros((v, 3)), "joint_count": j})()
        assert np.array_equal(owner_joints(av), np.argmax(joint_weight_matrix(av), axis=1))
        score = rng.choice([0.0, 0.1, 0.5, 1.0, rng.uniform()], (v, j)) * (rng.uniform(size=(v, j)) > 0.3)
        for k in (1, 3, 4, 12):
            order = np.argsort(-score, axis=1, kind="stable")[:, :k]
            best = np.take_along_axis(score, order, axis=1)
            got_j, got_s = top_k(score, k)
            assert np.array_equal(got_j, np.where(best > 0, order, 0)) and np.array_equal(got_s, np.where(best > 0, best, 0))


def _raster_union_area(xy, radii, cells=1500):
    """The union's area counted on a grid of cells x cells over its bounding box (float64; the
    error is about the boundary's length times a cell)."""
    on = radii > 0
    if not on.any():
        return 0.0, 0.0
    c, r = xy[on], radii[on]
    lo, hi = (c - r[:, None]).min(0), (c + r[:, None]).max(0)
    step = (hi - lo) / cells
    gx = lo[0] + (np.arange(cells) + 0.5) * step[0]
    gy = lo[1] + (np.arange(cells) + 0.5) * step[1]
    inside = np.zeros((cells, cells), bool)
    for (cx, cy), rr in zip(c, r):
        inside |= ((gx[None, :] - cx) ** 2 + (gy[:, None] - cy) ** 2) <= rr * rr
    boundary = 2 * np.pi * r.sum()
    return float(inside.sum() * step[0] * step[1]), float(boundary * max(step))


def test_the_union_of_disks_against_a_raster_count_and_exact_cases():
    """``union_disk_area`` (a window of disks by x, arcs of each disk's free boundary) against an
    independent grid count of the union, and against cases with a closed form: concentric disks
    (the largest), disjoint disks (the sum), two equal disks (the lens formula)."""
    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 60):
        for t in range(4):
            xy = rng.normal(size=(n, 2)) * rng.uniform(0.2, 4)
            r = rng.uniform(0, 1, n) * (rng.uniform(size=n) > 0.1)
            if t == 1:
                r[:] = 0.5         # equal disks
            want, tol = _raster_union_area(xy, r)
            assert abs(union_disk_area(xy, r) - want) <= tol + 1e-12
    r = np.array([0.3, 1.0, 0.7])
    assert union_disk_area(np.zeros((3, 2)), r) == pytest.approx(np.pi, rel=1e-12)          # concentric
    xy = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 9.0]])
    assert union_disk_area(xy, r) == pytest.approx(np.pi * (r ** 2).sum(), rel=1e-12)      # disjoint
    d = 0.6                                                                                # two unit disks
    lens = 2 * np.arccos(d / 2) - d / 2 * np.sqrt(4 - d * d)
    assert union_disk_area(np.array([[0.0, 0.0], [d, 0.0]]), np.ones(2)) == pytest.approx(2 * np.pi - lens, rel=1e-12)


def test_counts_are_read_from_the_json_before_the_buffers(tmp_path):
    for name, gltf, joints in (("walker.glb", walker_gltf(), 11), ("bones.glb", many_bone_gltf(30, keyframes=7), 30)):
        path = tmp_path / name
        gltf.save_binary(str(path))
        counts = read_counts(path)
        av = load_avatar(path)
        assert (counts.vertices, counts.joints, counts.keyframes) == (len(av.positions), joints, len(av.animations[0].keyframes))
        assert counts.file_bytes == path.stat().st_size
    assert read_counts(path, animation=None).keyframes == 1
    (tmp_path / "junk.glb").write_bytes(b"glTF\x02\x00\x00\x00junk")
    assert read_counts(tmp_path / "junk.glb") is None   # the loader says what is wrong
    est = estimate_avatar(AvatarCounts(vertices=460_000, joints=5000, keyframes=5, objects=20_000, file_bytes=35_000_000))
    assert est.big and "460,000 vertices x 5,000 joints x 5 keyframes" in est.describe()
    assert est.peak_bytes < 2**30 and est.seconds > 600     # memory bounded, the time is what grows


def test_too_many_bones_for_the_memory_limit_is_one_line_before_reading(tmp_path):
    src = tmp_path / "bones.glb"
    many_bone_gltf(200).save_binary(str(src))
    out = tmp_path / "out" / "o.glb"
    t0 = time.perf_counter()
    r = _envcap("avatar", src, "--out", out, env={"ENVCAP_MAX_MEMORY": "100M"})
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("envcap: error: avatar ")
    assert "18,308 vertices x 200 joints x 5 keyframes" in r.stderr and "more than the 100 MiB memory limit" in r.stderr
    assert time.perf_counter() - t0 < 30
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bones.glb"]   # nothing created, not even the folder


@pytest.mark.slow
def test_a_long_run_prints_its_estimate_and_the_next_run_removes_what_a_kill_left(tmp_path):
    src = tmp_path / "bones.glb"
    many_bone_gltf(200, keyframes=100).save_binary(str(src))    # estimated at > 1 min: the estimate comes first
    out = tmp_path / "o.glb"
    proc = _envcap("avatar", src, "--out", out, background=True)
    lines: list[str] = []
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not any(ln.startswith("progress: read") for ln in lines):
            line = proc.stderr.readline()
            if not line:
                break
            lines.append(line)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        proc.stderr.close()
        proc.stdout.close()
    assert lines and lines[0].startswith(f"{src}: estimate: 18,308 vertices x 200 joints x 100 keyframes"), lines
    assert "progress: read" in lines[-1], lines
    left = sorted(p.name for p in tmp_path.iterdir())
    assert ".o.glb.lock" in left and any(re.fullmatch(r"\.o\.glb\.tmp-[0-9a-f]{8}\.glb", n) for n in left), left
    old_style = tmp_path / ".o.glb.tmp-k_3x9qz1.glb"      # tempfile's names (earlier versions): envcap's too
    old_style.write_bytes(b"")
    mine = [".o.glb.tmp-abc.glb", ".o.glb.tmp-ABCDEFGH.glb", "o.glb.tmp-12345678.glb", ".o.glb.tmp-12345678.glb.keep",
            ".p.glb.tmp-12345678.glb"]
    for name in mine:
        (tmp_path / name).write_bytes(b"user's")
    (tmp_path / ".o.glb.tmp-0000aaaa.glb").mkdir()        # a folder of that name is not envcap's file
    walker = tmp_path / "walker.glb"
    walker_gltf().save_binary(str(walker))
    r = _envcap("avatar", walker, "--out", out, "--quiet")
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["bones.glb", "o.glb", "walker.glb",
                                                                 ".o.glb.tmp-0000aaaa.glb", *mine])
    assert all((tmp_path / name).read_bytes() == b"user's" for name in mine)
