"""Crash safety of a real bake: SIGTERM and SIGKILL at random (seeded) points of
``envcap capture planes --resolution 16``, each on top of a complete previous output.

After every signal the output is a complete output (the previous one byte for byte, or, if the
signal came after the new one was in place, the new one); a run stopped by SIGTERM leaves
nothing of its own; the next run that gets to work removes what SIGKILL left; the final uninterrupted rerun is bit-identical to the
first run (the manifest's run times aside).
"""

import random
import signal
import time

import pytest
from envcap_process import error_lines, run_envcap, start_envcap, tree_bytes, without_timings

from envcap.outputs import MARKER_NAME

SEED = 9


def _phases(tmp_path, proc):
    """Seconds from the start until the lock appears, until the temporary output appears, and
    until the process ends (polled every few milliseconds)."""
    t0 = time.monotonic()
    t_lock = t_tmp = None
    while proc.poll() is None:
        now = time.monotonic() - t0
        if t_lock is None and (tmp_path / ".out.lock").exists():
            t_lock = now
        if t_tmp is None and any(tmp_path.glob(".out.tmp-*")):
            t_tmp = now
        time.sleep(0.003)
    return t_lock, t_tmp, time.monotonic() - t0


def _wait(tmp_path, proc, anchor, left_before):
    """Wait until ``proc`` holds the lock (the lock file names its pid) or has created its own
    temporary output (not one that a killed run left)."""
    def reached():
        if anchor == "lock":
            try:
                return (tmp_path / ".out.lock").read_text().strip() == str(proc.pid)
            except OSError:
                return False
        return any(p.name not in left_before for p in tmp_path.glob(".out.tmp-*"))

    while proc.poll() is None and not reached():
        time.sleep(0.003)


def _leftovers(tmp_path):
    return sorted(p.name for p in tmp_path.iterdir() if p.name != "out")


@pytest.mark.slow
def test_sigterm_and_sigkill_at_random_points_never_cost_the_previous_output(tmp_path):
    rng = random.Random(SEED)
    out = tmp_path / "out"
    cmd = ("capture", "planes", "--out", out, "--resolution", "16")
    first = start_envcap(*cmd)
    t_lock, t_tmp, t_end = _phases(tmp_path, first)
    assert first.wait() == 0, first.stderr.read()
    assert t_lock is not None and t_tmp is not None and t_lock < t_tmp < t_end
    reference = without_timings(tree_bytes(out))
    assert MARKER_NAME in reference and "probes.ktx2" in reference
    # Each signal at a random point of one of three phases: start-up, bake (lock held), writing.
    windows = {"start": t_lock, "lock": t_tmp - t_lock, "temp": t_end - t_tmp}
    plan = [(sig, anchor) for sig in (signal.SIGTERM, signal.SIGKILL) for anchor in windows]
    rng.shuffle(plan)
    outcomes = []
    for sig, anchor in plan:
        before, left_before = tree_bytes(out), _leftovers(tmp_path)
        proc = start_envcap(*cmd)
        if anchor != "start":
            _wait(tmp_path, proc, anchor, left_before)
        time.sleep(rng.uniform(0.0, windows[anchor]))
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=300)
        now = tree_bytes(out)
        kept = now == before
        assert kept or without_timings(now) == reference, (sig, anchor, proc.returncode)
        if sig == signal.SIGTERM:
            assert proc.returncode in (143, -signal.SIGTERM, 0), err  # -15: before envcap's handler
            if proc.returncode == 143:
                assert error_lines(err) == ["envcap: terminated"], err
            assert set(_leftovers(tmp_path)) <= set(left_before), (anchor, _leftovers(tmp_path))  # none of its own
        else:
            assert proc.returncode in (-signal.SIGKILL, 0), err
        outcomes.append((sig.name, anchor, proc.returncode, "old kept" if kept else "new in place",
                         _leftovers(tmp_path)))
    print("\n".join(map(str, outcomes)))
    assert sum(o[2] == 143 for o in outcomes) >= 1 and sum(o[2] == -9 for o in outcomes) >= 1, outcomes
    rerun = run_envcap(*cmd)
    assert rerun.returncode == 0, rerun.stderr
    assert _leftovers(tmp_path) == []  # no temporary folder, no lock survives the next run
    assert without_timings(tree_bytes(out)) == reference  # bit-identical to the uninterrupted run
