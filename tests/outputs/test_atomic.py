"""Atomic outputs: nothing half-written on failure, usual permissions on success, the marker on
every output directory, and only envcap's own outputs replaced."""

import json
import os
import stat

import pytest

from envcap import __version__
from envcap.outputs import MARKER_NAME, OutputRefused, atomic_output_dir, atomic_output_file


def test_failed_run_leaves_nothing_and_keeps_old_output(tmp_path):
    out = tmp_path / "set"
    with atomic_output_dir(out) as d:
        (d / "a.txt").write_text("old")
    with pytest.raises(RuntimeError), atomic_output_dir(out) as d:
        (d / "a.txt").write_text("new, half")
        raise RuntimeError("boom")
    assert (out / "a.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["set"]


def test_outputs_get_the_umask_mode_not_owner_only(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_output_dir(tmp_path / "d") as d:
            (d / "x").write_text("1")
        with atomic_output_file(tmp_path / "f.txt") as f:
            f.write_text("2")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "d").stat().st_mode) == 0o755
    assert stat.S_IMODE((tmp_path / "f.txt").stat().st_mode) == 0o644


def test_failed_file_write_leaves_nothing(tmp_path):
    with pytest.raises(ValueError), atomic_output_file(tmp_path / "f.bin") as f:
        f.write_bytes(b"half")
        raise ValueError("bad")
    assert list(tmp_path.iterdir()) == []


def test_every_output_directory_carries_the_marker(tmp_path):
    with atomic_output_dir(tmp_path / "set", kind="probe-set") as d:
        (d / "a.txt").write_text("x")
    marker = json.loads((tmp_path / "set" / MARKER_NAME).read_text())
    assert marker == {"envcap_output": "probe-set", "envcap_version": __version__}
    assert sorted(p.name for p in (tmp_path / "set").iterdir()) == sorted([MARKER_NAME, "a.txt"])


def test_a_foreign_non_empty_directory_is_refused_unless_forced(tmp_path):
    mine = tmp_path / "photos"
    mine.mkdir()
    (mine / "holiday.jpg").write_bytes(b"precious")
    with pytest.raises(OutputRefused, match="not written by envcap.*--force"):
        with atomic_output_dir(mine) as d:
            (d / "a.txt").write_text("x")
    assert [p.name for p in mine.iterdir()] == ["holiday.jpg"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photos"]  # no temp, no lock left
    with atomic_output_dir(mine, force=True) as d:
        (d / "a.txt").write_text("x")
    assert sorted(p.name for p in mine.iterdir()) == sorted([MARKER_NAME, "a.txt"])


def test_an_empty_directory_or_a_marked_one_is_replaced(tmp_path):
    (tmp_path / "empty").mkdir()
    with atomic_output_dir(tmp_path / "empty") as d:
        (d / "a").write_text("1")
    with atomic_output_dir(tmp_path / "empty") as d:  # now marked: replaced without force
        (d / "b").write_text("2")
    assert sorted(p.name for p in (tmp_path / "empty").iterdir()) == sorted([MARKER_NAME, "b"])


def test_the_marker_is_checked_again_before_the_swap(tmp_path):
    out = tmp_path / "set"
    with pytest.raises(OutputRefused, match="not written by envcap"):
        with atomic_output_dir(out) as d:
            (d / "new").write_text("1")
            out.mkdir()
            (out / "appeared.txt").write_text("a user's file, written while envcap worked")
    assert [p.name for p in out.iterdir()] == ["appeared.txt"]


def test_the_working_directory_and_its_ancestors_are_never_outputs(tmp_path, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    (work / "notes.txt").write_text("keep")
    monkeypatch.chdir(work)
    for target in (".", "..", str(work)):
        with pytest.raises(OutputRefused, match="working directory"):
            with atomic_output_dir(target, force=True):
                pass
    assert (work / "notes.txt").read_text() == "keep"


def test_a_file_or_a_path_below_a_file_is_refused_before_the_block_runs(tmp_path):
    (tmp_path / "f").write_text("x")
    ran = []
    for target, words in ((tmp_path / "f", "not a directory"), (tmp_path / "f" / "sub", "f is not a directory")):
        with pytest.raises(OutputRefused, match=words):
            with atomic_output_dir(target, force=True):
                ran.append(target)
    assert ran == [] and (tmp_path / "f").read_text() == "x"


def test_missing_parents_are_created_and_removed_again_on_failure(tmp_path):
    with pytest.raises(RuntimeError):
        with atomic_output_dir(tmp_path / "a" / "b" / "set"):
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
    with atomic_output_dir(tmp_path / "a" / "b" / "set") as d:
        (d / "x").write_text("1")
    assert (tmp_path / "a" / "b" / "set" / "x").read_text() == "1"
