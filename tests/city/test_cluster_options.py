"""City options that once hung, leaked a traceback, started too many processes or were ignored
(issue 20): each is now one line ``envcap: error: ...``, exit 2, at once, before any output is
claimed; ``--quiet`` silences a city bake's progress."""

import socket
import time

import pytest

from envcap.city.capacity import usable_cores
from envcap.cli import main

BAKE = ["capture", "crossing", "--resolution", "8", "--spacing", "100"]


def _closed_port() -> int:
    with socket.socket() as s:          # bound, never listening: connections are refused
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _one_line(capsys, rc, *words):
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and err.startswith("envcap: error:"), err
    for w in words:
        assert w in err, (w, err)
    return err


@pytest.mark.parametrize("address, words", [
    ("", ["--scheduler needs an address", "''"]),
    ("tcp://127.0.0.1:99999", ["port must be a number in 1-65535", "99999"]),
    ("tcp://127.0.0.1:CLOSED", ["connection refused", "127.0.0.1"]),
    ("http://127.0.0.1:8786", ["unknown scheme 'http'"]),
])
def test_a_scheduler_address_is_checked_at_once_before_any_output(tmp_path, capsys, address, words):
    """Old: '' and a closed port waited 30 s and left a city folder (marker + shards/)."""
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        address = address.replace("CLOSED", str(held.getsockname()[1]))
        t0 = time.monotonic()
        rc = main([*BAKE, "--out", str(tmp_path / "city"), "--scheduler", address])
    assert time.monotonic() - t0 < 10
    _one_line(capsys, rc, *words)
    assert list(tmp_path.iterdir()) == []


def test_workers_beside_a_scheduler_is_an_error(tmp_path, capsys):
    """Old: --workers was silently ignored beside --scheduler."""
    rc = main([*BAKE, "--out", str(tmp_path / "city"), "--workers", "2", "--scheduler", f"tcp://127.0.0.1:{_closed_port()}"])
    _one_line(capsys, rc, "--workers", "--scheduler", "give one of them")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("mb", ["inf", "nan", "1e300", "-1", "1000001"])
def test_shard_mb_is_a_finite_number_in_range(tmp_path, capsys, mb):
    """Old: --shard-mb inf was an OverflowError traceback."""
    rc = main([*BAKE, "--out", str(tmp_path / "city"), "--workers", "0", "--shard-mb", mb])
    _one_line(capsys, rc, "--shard-mb must be >= 0 and at most 1e+06 MB")
    assert list(tmp_path.iterdir()) == []


def test_more_workers_than_cores_are_refused_saying_what_the_machine_holds(tmp_path, capsys):
    """Old: --workers 1000 started 1,000 processes on 2 cores.  Here: one more than the cores."""
    n = usable_cores() + 1
    t0 = time.monotonic()
    rc = main([*BAKE, "--out", str(tmp_path / "city"), "--workers", str(n)])
    assert time.monotonic() - t0 < 10
    _one_line(capsys, rc, f"--workers {n}: this machine holds at most {n - 1} worker(s)", f"{n - 1} CPU core(s)",
              "per worker", f"use --workers {n - 1} or fewer")
    assert list(tmp_path.iterdir()) == []


def test_workers_past_the_memory_limit_are_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "150M")          # less than one worker's process baseline
    rc = main([*BAKE, "--out", str(tmp_path / "city"), "--workers", "1"])
    _one_line(capsys, rc, "at most 0 worker(s)", "150 MiB of memory (ENVCAP_MAX_MEMORY)", "--workers 0")
    assert list(tmp_path.iterdir()) == []


def test_quiet_silences_a_city_bake(tmp_path, capsys, gl_ctx):
    """Old: --quiet was ignored by city bakes (plan and shard lines on stderr)."""
    assert main([*BAKE, "--out", str(tmp_path / "city"), "--workers", "0", "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and out.startswith("wrote city probe set of 'crossing'")
    assert (tmp_path / "city" / "city.json").is_file()
