"""Resumable and identical: a city bake killed (SIGKILL) while it writes a shard, then resumed,
gives the same bytes as an uninterrupted run; a Dask run gives the same bytes as one process; a
rerun skips finished shards and other inputs replace stale ones."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from envcap.city.bake import bake_city
from envcap.city.plan import BakeSettings
from envcap.cli import main

from city_fixtures import SETTINGS, tree

ARGS = ["capture", "crossing", "--workers", "0", "--resolution", "8", "--spacing", "100", "--shard-mb", "0"]
ROOT = Path(__file__).resolve().parents[2]


def _kill_while_writing_a_shard(out: Path) -> bool:
    """Run ``envcap capture`` in a subprocess and SIGKILL it as soon as a shard's temporary
    directory or lock appears (mid-write); True if it was killed before finishing."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "envcap", *ARGS, "--out", str(out)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline:
            shards = out / "shards"
            if shards.is_dir() and any(p.name.startswith(".") for p in shards.iterdir()):
                proc.send_signal(signal.SIGKILL)
                break
            time.sleep(0.002)
        return proc.wait(timeout=60) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()


def test_a_bake_killed_mid_write_and_resumed_is_bit_identical(tmp_path, gl_ctx):
    killed = tmp_path / "killed"
    assert _kill_while_writing_a_shard(killed), "the bake finished before it could be killed"
    left = tree(killed)
    assert "city.json" not in left and any(".tmp-" in k or k.endswith(".lock") for k in left)
    assert main([*ARGS, "--out", str(killed)]) == 0
    whole = tmp_path / "whole"
    assert main([*ARGS, "--out", str(whole)]) == 0
    assert tree(killed) == tree(whole)


def test_a_dask_bake_is_bit_identical_to_one_process_and_loads_the_scene_once_per_worker(tmp_path, crossing_city):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cl:
        r = bake_city("crossing", tmp_path / "d", BakeSettings(**SETTINGS), budget_mb=0, scheduler=cl.scheduler_address)
    assert r.baked == 2 and len(r.workers) == 2
    assert all(w["scene_loads"] <= 1 for w in r.workers.values()) and sum(w["scene_loads"] for w in r.workers.values()) >= 1
    assert tree(tmp_path / "d") == tree(crossing_city)


def test_a_rerun_skips_finished_shards_and_new_inputs_replace_stale_ones(tmp_path, crossing_city, gl_ctx):
    import shutil
    city = tmp_path / "c"
    shutil.copytree(crossing_city, city)
    before = tree(city)
    r = bake_city("crossing", city, BakeSettings(**SETTINGS), budget_mb=0, ctx=gl_ctx)
    assert (r.baked, r.skipped) == (0, 2) and tree(city) == before
    r = bake_city("crossing", city, BakeSettings(**SETTINGS), budget_mb=1, ctx=gl_ctx)  # both streets in one shard
    assert (r.baked, r.skipped) == (1, 0)
    assert len(list((city / "shards").iterdir())) == 1


@pytest.mark.slow
def test_a_worker_killed_while_it_writes_a_shard_is_replaced_and_the_bits_are_the_same(tmp_path, gl_ctx):
    """Issue 11: "Tasks are retried on worker loss".  A worker process is SIGKILLed as soon as it
    has a file open in its temporary shard folder (``envcap-shard-*``: a worker writes a shard on
    its own disk and sends the bytes back, issue 19); the scheduler reschedules its task and the
    city has the bytes of a one-process bake."""
    distributed = pytest.importorskip("distributed")
    import threading

    settings = BakeSettings(**{**SETTINGS, "resolution": 32})      # shards that take long enough to be caught
    bake_city("crossing", tmp_path / "one", settings, budget_mb=0, ctx=gl_ctx)
    out = tmp_path / "lost"
    killed: list[int] = []
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl, \
            distributed.Client(cl) as client:
        pids = list(client.run(os.getpid).values())

        def kill_one_mid_write() -> None:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and not killed:
                for pid in pids:
                    try:
                        busy = any("/envcap-shard-" in os.readlink(f"/proc/{pid}/fd/{fd}")
                                   for fd in os.listdir(f"/proc/{pid}/fd"))
                    except OSError:
                        continue
                    if busy:
                        os.kill(pid, signal.SIGKILL)
                        killed.append(pid)
                        break
                time.sleep(0.002)

        watcher = threading.Thread(target=kill_one_mid_write)
        watcher.start()
        try:
            r = bake_city("crossing", out, settings, budget_mb=0, scheduler=cl.scheduler_address)
        finally:
            if not killed:
                killed.append(-1)                                   # stops the watcher
            watcher.join()
    assert killed[0] in pids, "no worker was killed: the bake ended first"
    assert r.baked == 2
    assert tree(out) == tree(tmp_path / "one")
