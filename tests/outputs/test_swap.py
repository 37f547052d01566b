"""The swap of old and new output never leaves the output path missing, and the next writer
recovers whatever a killed one left (half-done two-step swap, temporary directories)."""

import subprocess
import sys
import time

import pytest

from envcap.outputs import MARKER_NAME, OutputBusy, atomic_output_dir, claim_output_dir
from envcap.outputs.marker import write_marker
from envcap.outputs.swap import HAS_EXCHANGE, aside_path, install, journal_path, make_temp_dir, recover

# Polls the output path in a tight loop from another process; prints "missing" and exits at the
# first instant the path is not a directory, prints "present" when told to stop.
WATCHER = """
import os, sys
path, stop = sys.argv[1], sys.argv[2]
print("ready", flush=True)
while not os.path.exists(stop):
    if not os.path.isdir(path):
        print("missing", flush=True)
        sys.exit(0)
print("present", flush=True)
"""


def _watch(final, stop):
    w = subprocess.Popen([sys.executable, "-c", WATCHER, str(final), str(stop)], stdout=subprocess.PIPE, text=True)
    assert w.stdout.readline().strip() == "ready"
    return w


def _swap_until(final, use_exchange, swaps, watcher):
    for i in range(swaps):
        tmp = make_temp_dir(final)
        (tmp / "i").write_text(str(i))
        install(tmp, final, use_exchange=use_exchange)
        if watcher.poll() is not None:
            return i + 1
    return swaps


@pytest.mark.skipif(not HAS_EXCHANGE, reason="no renameat2(RENAME_EXCHANGE) on this system")
def test_the_output_path_never_goes_missing_during_a_swap(tmp_path):
    final = tmp_path / "out"
    final.mkdir()
    # Control: two plain renames (old aside, new in) leave a gap the watcher can see.
    w = _watch(final, tmp_path / "stop1")
    done = _swap_until(final, False, 5000, w)
    (tmp_path / "stop1").touch()
    assert w.communicate(timeout=30)[0].strip() == "missing", f"the watcher saw no gap in {done} two-step swaps"
    # The exchange: 1000 swaps, the watcher polling all along, never a gap.
    w = _watch(final, tmp_path / "stop2")
    _swap_until(final, True, 1000, w)
    (tmp_path / "stop2").touch()
    assert w.communicate(timeout=30)[0].strip() == "present"
    assert (final / "i").read_text() == "999"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "stop1", "stop2"]


def test_two_step_swap_replaces_and_leaves_nothing(tmp_path):
    final = tmp_path / "out"
    final.mkdir()
    (final / "old").write_text("old")
    tmp = make_temp_dir(final)
    (tmp / "new").write_text("new")
    install(tmp, final, use_exchange=False)
    assert [p.name for p in final.iterdir()] == ["new"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def _killed_between_renames(tmp_path):
    """The on-disk state of a writer killed between the two renames of a two-step swap: the
    journal, the old output set aside, the new complete output under its temporary name."""
    final = tmp_path / "set"
    old = aside_path(final)
    old.mkdir()
    (old / "data").write_text("old output")
    write_marker(old, "probe-set")
    new = make_temp_dir(final)
    (new / "data").write_text("new output")
    journal_path(final).touch()
    return final


def test_the_next_run_puts_back_an_output_set_aside_by_a_killed_swap(tmp_path):
    final = _killed_between_renames(tmp_path)
    assert not final.exists()
    with claim_output_dir(final):
        assert (final / "data").read_text() == "old output"  # recovered before any work
    assert sorted(p.name for p in tmp_path.iterdir()) == ["set"]


def test_recovery_then_the_new_output(tmp_path):
    final = _killed_between_renames(tmp_path)
    with atomic_output_dir(final) as d:
        (d / "data").write_text("newest")
    assert (final / "data").read_text() == "newest"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["set"]


def test_a_set_aside_copy_without_journal_is_garbage_not_an_output(tmp_path):
    """Killed while removing the old output after a complete swap, then the user deleted the
    output: the half-removed old copy must not come back."""
    final = tmp_path / "set"
    old = aside_path(final)
    old.mkdir()
    (old / "half").write_text("x")
    assert recover(final) == [old]
    assert list(tmp_path.iterdir()) == []


def test_only_envcaps_own_temporary_names_are_removed(tmp_path):
    final = tmp_path / "set"
    stale = [tmp_path / ".set.tmp-0123abcd", tmp_path / ".set.tmp-ffffffff"]
    for d in stale:
        d.mkdir()
        (d / "probes.ktx2").write_bytes(b"\0" * 1000)
    others = [tmp_path / ".set.tmp-notours", tmp_path / ".other.tmp-0123abcd", tmp_path / ".set.tmp-0123abcd.keep",
              tmp_path / "set.tmp-0123abcd"]
    for d in others:
        d.mkdir()
    with atomic_output_dir(final) as d:
        (d / "x").write_text("1")
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(["set"] + [d.name for d in others])
    assert sorted(p.name for p in final.iterdir()) == sorted([MARKER_NAME, "x"])


HOLDER = """
import sys, time
from envcap.outputs import atomic_output_dir
with atomic_output_dir(sys.argv[1]) as d:
    (d / "partial.bin").write_bytes(b"x" * 4096)
    print(d, flush=True)
    time.sleep(120)
"""


def test_a_live_writers_temporary_directory_is_left_alone_and_a_killed_ones_removed(tmp_path):
    final = tmp_path / "set"
    with atomic_output_dir(final) as d:
        (d / "v").write_text("1")
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(final)], stdout=subprocess.PIPE, text=True)
    try:
        live_tmp = holder.stdout.readline().strip()
        assert live_tmp and (tmp_path / live_tmp).is_dir()
        with pytest.raises(OutputBusy, match="another envcap run"):
            with atomic_output_dir(final):
                pass
        assert (tmp_path / live_tmp / "partial.bin").is_file()  # the live run's work is untouched
    finally:
        holder.kill()  # SIGKILL: no clean-up runs in the holder
        holder.wait(timeout=30)
    assert (tmp_path / live_tmp).is_dir()  # what SIGKILL leaves
    t0 = time.perf_counter()
    with atomic_output_dir(final) as d:
        (d / "v").write_text("2")
    assert time.perf_counter() - t0 < 5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["set"]
    assert (final / "v").read_text() == "2"
