"""A city bake whose cluster fails under it (issue 20), with real processes: a ``dask scheduler``
killed or frozen mid-bake, and SIGTERM / Ctrl-C to the client of a ``LocalCluster``.  Each ends
in one line and a known exit status, keeps the finished shards (a rerun resumes), leaves no
temporary name or lock, and leaves no process behind.

Old behaviour: a killed scheduler gave a ``FutureCancelledError`` traceback; a frozen one hung the
bake forever; ``--quiet`` was ignored, so a signal's one line came among progress lines.
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dask_processes import Drained, free_port, session_processes, stop_session, wait_gone
from envcap.city.capacity import usable_cores

REPO = Path(__file__).resolve().parents[2]
BAKE = ["capture", "crossing", "--resolution", "32", "--spacing", "5", "--shard-mb", "0", "--quiet"]  # 2 shards, ~3 s each
LONG = [*BAKE[:3], "64", *BAKE[4:]]                                     # ~10 s each: signals land mid-bake


def _env() -> dict[str, str]:
    return dict(os.environ, PYOPENGL_PLATFORM="egl",
                PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))


def _start(args: list[str], cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(args, cwd=cwd, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _wait_for_shard(city: Path, proc: subprocess.Popen[str], timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        shards = city / "shards"
        if shards.is_dir() and any(p.name[0].isdigit() for p in shards.iterdir()):
            return
        time.sleep(0.02)
    raise AssertionError(f"no shard appeared (exit {proc.poll()}): {proc.stderr.read() if proc.poll() is not None else ''}")


def _left_clean(parent: Path) -> None:
    """Nothing of envcap's own temporary names or locks next to or inside the city."""
    odd = [p for p in parent.rglob(".*") if ".tmp-" in p.name or p.name.endswith(".lock")]
    assert odd == [], odd


@pytest.fixture
def scheduler(tmp_path):
    """A ``dask scheduler`` and one ``dask worker`` (one thread) on 127.0.0.1, in directories of
    their own; yields (address, scheduler process); both stopped whatever happens."""
    port = free_port()
    started = []
    try:
        for name, args, ready in (
                ("scheduler", ["dask", "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                 "Scheduler at:"),
                ("worker", ["dask", "worker", f"tcp://127.0.0.1:{port}", "--nworkers", "1", "--nthreads", "1",
                            "--no-dashboard"], "Registered to:")):
            (tmp_path / name).mkdir()
            proc = subprocess.Popen(args, cwd=tmp_path / name, env=_env(), stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, text=True, start_new_session=True)
            started.append(proc)
            Drained(proc).wait_for(ready, 60)
        yield f"tcp://127.0.0.1:{port}", started[0]
    finally:
        for proc in reversed(started):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGCONT)
            stop_session(proc)


@pytest.mark.slow
def test_a_scheduler_killed_mid_bake_is_one_line_and_the_rerun_resumes(scheduler, tmp_path):
    address, sched = scheduler
    work = tmp_path / "work"
    work.mkdir()
    bake = _start([sys.executable, "-m", "envcap", *BAKE, "--out", "city", "--scheduler", address,
                   "--cluster-timeout", "3"], work)
    try:
        _wait_for_shard(work / "city", bake)
        os.killpg(sched.pid, signal.SIGKILL)
        _, err = bake.communicate(timeout=60)
    finally:
        stop_session(bake)
    assert bake.returncode == 2 and err.count("\n") == 1, err
    assert err.startswith(f"envcap: error: the Dask scheduler at {address} went away mid-bake")
    assert "1 of 2 shard(s) done and kept: rerun the same command to resume" in err
    _left_clean(work)
    r = subprocess.run([sys.executable, "-m", "envcap", *BAKE, "--out", "city", "--workers", "0"], cwd=work, env=_env(),
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "1 shard(s) baked, 1 already done" in r.stdout, r.stderr


@pytest.mark.slow
def test_a_frozen_scheduler_is_one_line_after_the_timeout(scheduler, tmp_path):
    address, sched = scheduler
    work = tmp_path / "work"
    work.mkdir()
    bake = _start([sys.executable, "-m", "envcap", *BAKE, "--out", "city", "--scheduler", address,
                   "--cluster-timeout", "2"], work)
    try:
        _wait_for_shard(work / "city", bake)
        os.killpg(sched.pid, signal.SIGSTOP)
        t0 = time.monotonic()
        _, err = bake.communicate(timeout=60)
        took = time.monotonic() - t0
    finally:
        stop_session(bake)
    assert bake.returncode == 2 and err.count("\n") == 1, err
    assert f"the Dask scheduler at {address} stopped answering" in err and "rerun the same command" in err, err
    assert took < 15, f"{took:.1f} s after the scheduler froze"
    _left_clean(work)


@pytest.mark.slow
@pytest.mark.parametrize("sig, to_group, status, line", [
    (signal.SIGTERM, False, 143, "envcap: terminated"),
    (signal.SIGINT, True, 130, "envcap: interrupted"),        # Ctrl-C: the terminal signals the whole group
])
def test_a_signal_to_the_client_shuts_its_local_cluster_down(tmp_path, sig, to_group, status, line):
    workers = min(2, usable_cores())
    bake = _start([sys.executable, "-m", "envcap", *LONG, "--out", "city", "--workers", str(workers)], tmp_path)
    try:
        deadline = time.monotonic() + 120
        while len(session_processes(bake.pid)) < workers + 1 and time.monotonic() < deadline and bake.poll() is None:
            time.sleep(0.05)                                      # the workers (and multiprocessing's tracker)
        time.sleep(2.0)                                           # mid-bake
        assert bake.poll() is None, bake.stderr.read()
        os.killpg(bake.pid, sig) if to_group else bake.send_signal(sig)
        _, err = bake.communicate(timeout=60)
        left = wait_gone(bake.pid, 15)
    finally:
        stop_session(bake)
    assert bake.returncode == status and err == line + "\n", err
    assert left == [], f"processes left running: {left}"
    city = tmp_path / "city"
    assert not city.exists() or all(p.name[0].isdigit() for p in (city / "shards").iterdir())
    _left_clean(tmp_path)
