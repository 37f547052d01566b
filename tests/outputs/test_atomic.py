"""Atomic outputs: nothing half-written on failure, usual permissions on success."""

import os
import stat

import pytest

from envcap.core.atomic import atomic_output_dir, atomic_output_file


def test_failed_run_leaves_nothing_and_keeps_old_output(tmp_path):
    out = tmp_path / "set"
    with atomic_output_dir(out) as d:
        (d / "a.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_output_dir(out) as d:
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
    with pytest.raises(ValueError):
        with atomic_output_file(tmp_path / "f.bin") as f:
            f.write_bytes(b"half")
            raise ValueError("bad")
    assert list(tmp_path.iterdir()) == []
