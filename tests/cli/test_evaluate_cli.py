"""``envcap evaluate`` options that used to fail late or in someone else's words (issue 9): each is
now one line naming the option, exit 2, before any work, nothing left behind."""

from __future__ import annotations

import time

import pytest

from envcap.cli import main
from envcap.probeset.store import write_probe_set
from envcap.runtime import methods


@pytest.fixture(scope="module")
def probes_dir(tmp_path_factory, canyon_probe_set):
    return write_probe_set(tmp_path_factory.mktemp("ps") / "set", canyon_probe_set, previews=False, exr=False)


BASE = ["--positions", "1", "--resolution", "4", "--methods", "nearest", "--lobes", "inf,1", "--no-images"]

CASES = [
    # option changed, value, words the line must hold; old behaviour in the comment
    ("--positions", "100000000", ["--positions", "limit of 10,000", "peak memory"]),  # old: ran away
    ("--seed", "-1", ["--seed", ">= 0"]),                                  # old: "expected non-negative integer"
    ("--methods", "", ["--methods", "registered: nearest, planes"]),       # old: "unknown or no method(s) []"
    ("--methods", " , ", ["--methods", "registered:"]),
    ("--methods", "nearest,bogus", ["--methods", "'bogus'", "registered:"]),
    ("--resolution", "99999999999999999999", ["--resolution", "memory limit"]),  # old: "Maximum allowed size exceeded"
]


@pytest.mark.parametrize("option, value, words", CASES, ids=[f"{o}={v!r}" for o, v, _ in CASES])
def test_bad_evaluate_options_are_one_line_naming_the_option(probes_dir, tmp_path, capsys, option, value, words,
                                                             monkeypatch):
    monkeypatch.setenv("ENVCAP_MAX_MEMORY", "16G")
    argv = ["evaluate", "canyon", "--probes", str(probes_dir), "--out", str(tmp_path / "out"), *BASE]
    if option in argv:
        argv[argv.index(option) + 1] = value
    else:
        argv += [option, value]
    t0 = time.perf_counter()
    rc = main(argv)
    err = capsys.readouterr().err
    assert time.perf_counter() - t0 < 5.0
    assert rc == 2 and err.startswith("envcap: error: ") and err.count("\n") == 1, err
    assert all(w in err for w in words), err
    assert list(tmp_path.iterdir()) == []


def test_help_lists_the_registered_methods(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "registered: " + ", ".join(methods.registered()) in out
