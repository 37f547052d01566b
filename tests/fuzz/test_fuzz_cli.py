"""Fuzz the command line: ``envcap scenes / capture / prefilter / evaluate`` with generated numbers,
paths and options, in-process through ``envcap.cli.main(argv)`` (fast), and a few real
subprocess runs that check the exit status and the single ``envcap: error:`` line.

Every case starts from a small valid command and changes one argument (the message must then
name that option or path), or draws a whole argument list from a vocabulary.  Each runs in a
sandbox holding a copy of the session's probe set (``probes/``), its first EXR and a lat-long
EXR (``in/``), a scene file (``scenes/planes.toml``), a previous envcap output (``prev/``), a
user's own directory (``foreign/notes.txt``), an empty directory and a plain file: outputs may be
pointed at any of them, and only ``prev/`` (an envcap output that is no input) may be replaced.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from fuzz_harness import PINNED, REPO, fuzz_settings, require_names, run_case, settle
from fuzz_known import known_issue
from fuzz_sandbox import Sandbox, sandbox
from hypothesis import example, given
from hypothesis import strategies as st

from envcap.cli import main
from envcap.core.resources import city_scenes_dir

pytestmark = pytest.mark.slow  # property-based: up to tens of seconds per test

PATH_KINDS = ["out", "deep/a/b", "empty", "prev", "foreign", "afile.txt", "afile.txt/sub", ".", "..", "probes",
              "in", "scenes", "", "out/", "./x/../out2", "missing/../out3"]
"""Output paths (relative to the sandbox's work directory) a user might give."""

INT_TEXT = ["0", "-1", "1", "2", "3", "4", "7", "9", "16", "+4", " 4", "4.0", "1e3", "0x10", "abc", "", "-0",
            "100000", "99999999999999999999"]
"""Integer option values: edges, absurd sizes (a bounded run must refuse them at once), not-integers."""
FLOAT_TEXT = ["0", "-5", "nan", "inf", "-inf", "1e-9", "1e308", "1e309", "abc", "", "3", "-0.0", "1e6", "50", "1e-300"]
"""Float option values.  Between the absurd (1e-9 m spacing: 10^11 probes) and the sane there is a
range of legitimately long jobs (0.5 m spacing: 400 probes); generated numbers stay out of it."""

ints = st.one_of(st.sampled_from(INT_TEXT), st.integers(-3, 24).map(str))
floats = st.one_of(st.sampled_from(FLOAT_TEXT), st.floats(10, 1e4).map(repr), st.floats(-1e4, 0).map(repr))
names = st.sampled_from(["planes", "no_such_scene", "scenes/planes.toml", "scenes", "afile.txt", "in/probe.exr", "",
                         "missing.toml", "../scenes/planes.toml"])
inputs = st.sampled_from(["in/probe.exr", "in/sky.exr", "missing.exr", "in", "afile.txt", "scenes/planes.toml",
                          "probes/probes.ktx2", ""])
paths = st.sampled_from(PATH_KINDS)
junk = st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=8)

BASE: dict[str, list[str]] = {
    "scenes": ["scenes", "planes"],
    "capture": ["capture", "planes", "--out", "out", "--resolution", "4", "--spacing", "100", "--no-previews"],
    "prefilter": ["prefilter", "in/probe.exr", "--out", "out", "--size", "4"],
    "evaluate": ["evaluate", "planes", "--probes", "probes", "--out", "out", "--positions", "1", "--resolution", "4",
                 "--methods", "nearest", "--lobes", "inf,1", "--no-images"],
}
"""A small valid command each; one argument is then changed."""

OPTIONS: dict[str, dict[str, st.SearchStrategy[str]]] = {
    "scenes": {"scene": names, "--details": st.just(""), "--preview": paths},
    "capture": {"scene": names, "--out": paths, "--resolution": ints, "--spacing": floats, "--height": floats,
                "--quality": st.sampled_from(["fast", "default", "high", "ultra", ""]), "--sun-in-sky": st.just(""),
                "--no-exr": st.just("")},
    "prefilter": {"input": inputs, "--out": paths, "--size": ints,
                  "--quality": st.sampled_from(["fast", "default", "high", "best", ""])},
    "evaluate": {"scene": names, "--probes": paths, "--out": paths, "--positions": ints, "--seed": ints,
                 "--margin": floats, "--resolution": ints, "--bake": floats,
                 "--methods": st.one_of(st.sampled_from(["nearest", "nearest,blended", "bogus", ",", ""]), junk),
                 "--lobes": st.one_of(st.sampled_from(["inf", "mirror,4", "0", "-1", "nan", "1e400", "", ",", "4,4"]), junk)},
}
"""Per command: each argument and the text it may be given ("" for a flag: the flag is added)."""


def populate(sb: Sandbox, baked: Path, latlong_exr: Path) -> None:
    sb.copy(baked, "probes")
    sb.copy(baked, "prev")
    sb.copy(baked / "exr" / "probe_000.exr", "in/probe.exr")
    sb.copy(latlong_exr, "in/sky.exr")
    sb.copy(city_scenes_dir() / "planes.toml", "scenes/planes.toml")
    sb.write("foreign/notes.txt", "a user's own file: envcap must never delete it\n")
    sb.path("empty").mkdir()
    sb.write("afile.txt", "not a directory\n")


def changed(base: list[str], option: str, value: str) -> list[str]:
    """``base`` with ``option`` set to ``value`` (a positional when it has no dashes; a flag added)."""
    argv = list(base)
    if not option.startswith("--"):  # the positional right after the command
        argv[1] = value
        return argv
    if option in argv:
        i = argv.index(option)
        if value == "" and option in ("--details", "--sun-in-sky", "--no-exr", "--no-images"):
            return argv
        argv[i + 1] = value
        return argv
    if option in ("--details", "--sun-in-sky", "--no-exr"):
        return argv + [option]
    if option == "--bake":  # --bake replaces --probes (mutually exclusive)
        i = argv.index("--probes")
        return argv[:i] + ["--bake", value, "--probe-resolution", "4"] + argv[i + 2:]
    return argv + [option, value]


def _out_of(argv: list[str]) -> str | None:
    for opt in ("--out", "--preview"):
        if opt in argv and argv.index(opt) + 1 < len(argv):
            return argv[argv.index(opt) + 1]
    return None


def _inputs_of(argv: list[str]) -> list[str]:
    got = []
    if len(argv) > 1 and not argv[1].startswith("--"):
        got.append(argv[1])
    if "--probes" in argv and argv.index("--probes") + 1 < len(argv):
        got.append(argv[argv.index("--probes") + 1])
    return [g for g in got if g]


def check_argv(fuzz_base: Path, baked: Path, latlong_exr: Path, argv: list[str], *, mention: list[str],
               target: str, tolerate: bool, timeout: float = 8.0) -> None:
    with sandbox(fuzz_base) as sb:
        populate(sb, baked, latlong_exr)
        out = _out_of(argv)
        res = run_case(sb, lambda: main(list(argv)), cli=True, timeout=timeout,
                       out=sb.path(out) if out is not None else None,
                       inputs=[sb.path(p) for p in _inputs_of(argv)])
        require_names(res, *mention)
        settle(target, argv, res, known=known_issue if tolerate else None)


@st.composite
def one_change(draw: st.DrawFn) -> tuple[str, list[str], list[str]]:
    """``(command, argv, words a message about the change must contain one of)``."""
    cmd = draw(st.sampled_from(sorted(BASE)))
    option = draw(st.sampled_from(sorted(OPTIONS[cmd])))
    value = draw(OPTIONS[cmd][option])
    argv = changed(BASE[cmd], option, value)
    key = option.lstrip("-")
    mention = [key, option, "argument"]  # argparse names the argument ("argument --size: ...")
    if value.strip():
        mention += [value.strip(), Path(value).name or value]
    if option in ("scene", "input", "--probes", "--out") or key == "scene":
        mention += ["scene", "file", "directory", "not found", "exist"]
    return cmd, argv, [m for m in mention if m]


@fuzz_settings(30)
@given(case=one_change())
def test_one_changed_argument_runs_or_fails_in_one_line(fuzz_base, baked, latlong_exr, case):
    cmd, argv, mention = case
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=mention, target=f"cli.{cmd}", tolerate=True)


VOCAB = st.one_of(
    st.sampled_from(["scenes", "capture", "prefilter", "evaluate", "demo", "bench", "--out", "--resolution", "--spacing",
                     "--height", "--size", "--probes", "--bake", "--positions", "--seed", "--quality", "--details",
                     "--no-exr", "--no-previews", "--no-images", "--lobes", "--methods", "--help", "--version", "-h",
                     "--", "-", "--force"]),
    paths, ints, floats, names,
)


@fuzz_settings(15)
@given(argv=st.lists(VOCAB, min_size=0, max_size=7))
def test_any_argument_list_runs_or_fails_in_one_line(fuzz_base, baked, latlong_exr, argv):
    if any(a in ("demo", "bench") for a in argv[:1]):  # a full demo or benchmark is minutes of work
        argv = ["scenes", *argv[1:]]
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=[], target="cli.any", tolerate=True)


# --------------------------------------------------------------------------------------------
# Real processes: exit status 2 and one line


def run_envcap(args: list[str], cwd: Path, mem_gb: float = 2.0, timeout: float = 30) -> subprocess.CompletedProcess:
    """``python -m envcap ARGS`` from this checkout, with at most ``mem_gb`` of address space."""
    import resource

    def limit() -> None:
        n = int(mem_gb * (1 << 30))
        resource.setrlimit(resource.RLIMIT_AS, (n, n))

    env = dict(os.environ, PYTHONPATH=str(REPO), TMPDIR=str(cwd.parent / "tmp"))
    return subprocess.run([sys.executable, "-m", "envcap", *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, preexec_fn=limit, check=False)


SUBPROCESS_CASES = [
    (["capture", "planes", "--out", "out", "--spacing", "nan"], "spacing"),
    (["prefilter", "afile.txt", "--out", "out"], "afile.txt"),
    (["evaluate", "planes", "--probes", "foreign", "--out", "out"], "foreign"),
]
"""One bad number, one bad input file, one bad probe set: what the in-process cases check, in a real process."""


@pytest.mark.parametrize("args, word", SUBPROCESS_CASES, ids=[" ".join(a[:1] + a[-2:]) for a, _ in SUBPROCESS_CASES])
def test_a_real_run_exits_2_with_one_line(fuzz_base, baked, latlong_exr, args, word):
    with sandbox(fuzz_base) as sb:
        populate(sb, baked, latlong_exr)
        r = run_envcap(args, sb.work)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.returncode == 2, r.stderr
        assert len(lines) == 1 and lines[0].startswith("envcap: error: ") and word in lines[0], r.stderr
        assert not sb.path("out").exists()
        assert sorted(p.name for p in sb.tmp.iterdir()) == []


# --------------------------------------------------------------------------------------------
# Pinned: issue 9's reproducers (strict xfail where they fail today; regression checks elsewhere)


EVAL = ["evaluate", "planes", "--probes", "probes", "--out", "out", "--resolution", "4", "--methods", "nearest",
        "--lobes", "inf,1", "--no-images"]


@PINNED
@example(argv=["capture", "planes", "--out", "foreign", "--resolution", "4", "--spacing", "100", "--no-previews"])
@example(argv=["capture", "scenes/planes.toml", "--out", "scenes", "--resolution", "4", "--spacing", "100"])
@example(argv=["capture", "planes", "--out", ".", "--resolution", "4", "--spacing", "100", "--no-previews"])
@example(argv=[*EVAL[:4], "--positions", "1", "--out", "probes", *EVAL[6:]])
@example(argv=["prefilter", "probes/exr/probe_000.exr", "--out", "probes"])
@example(argv=["prefilter", "in/probe.exr", "--out", "in"])
@given(argv=st.builds(lambda out: ["prefilter", "in/probe.exr", "--out", out], st.sampled_from(["..", "in", "foreign"])))
def test_pinned_an_output_never_replaces_an_input_or_a_foreign_directory(fuzz_base, baked, latlong_exr, argv):
    """Issue 9 item 1 (data loss): --out at a user's directory, at the scene's folder, at '.', at
    the probe set being evaluated, at the folder of the prefilter input."""
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=["output", "out"], target="cli.pinned", tolerate=False)


@PINNED
@example(spacing="1e-9")
@given(spacing=st.sampled_from(["1e-7", "1e-12", "1e-300"]))
def test_pinned_a_tiny_spacing_is_refused_at_once(fuzz_base, baked, latlong_exr, spacing):
    argv = ["capture", "planes", "--out", "out", "--resolution", "4", "--spacing", spacing, "--no-previews"]
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=["spacing"], target="cli.pinned", tolerate=False, timeout=2.5)


@PINNED
@example(positions="100000000")
@given(positions=st.sampled_from(["1000000000", "2147483648"]))
def test_pinned_a_huge_sweep_is_refused_at_once(fuzz_base, baked, latlong_exr, positions):
    argv = [*EVAL[:6], "--positions", positions, *EVAL[6:]]
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=["positions"], target="cli.pinned", tolerate=False,
               timeout=2.5)


@PINNED
@example(seed="-1")
@given(seed=st.sampled_from(["-2", "-99999"]))
def test_pinned_a_negative_seed_is_named(fuzz_base, baked, latlong_exr, seed):
    argv = [*EVAL[:6], "--positions", "1", "--seed", seed, *EVAL[6:]]
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=["seed"], target="cli.pinned", tolerate=False)


@PINNED
@example(value="99999999999999999999")
@given(value=st.sampled_from(["18446744073709551616", "9" * 30]))
def test_pinned_an_integer_past_int64_is_named(fuzz_base, baked, latlong_exr, value):
    argv = ["capture", "planes", "--out", "out", "--resolution", value, "--spacing", "100", "--no-previews"]
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=["resolution"], target="cli.pinned", tolerate=False)


@PINNED
@example(value="99999999999999999999")
@given(value=st.sampled_from(["18446744073709551616", "9" * 30]))
def test_pinned_an_integer_past_int64_is_named_by_evaluate(fuzz_base, baked, latlong_exr, value):
    """evaluate's --resolution (the truth captures) is bounded before work (envcap/evaluate/bounds.py);
    old: numpy's 'Maximum allowed size exceeded', naming neither the option nor the cost."""
    argv = [*EVAL[:6], "--positions", "1", *EVAL[6:]]
    argv[argv.index("--resolution") + 1] = value
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=["resolution"], target="cli.pinned", tolerate=False)


@PINNED
@example(methods="")
@given(methods=st.sampled_from([",", " , "]))
def test_pinned_an_empty_method_list_is_named(fuzz_base, baked, latlong_exr, methods):
    argv = [*EVAL[:6], "--positions", "1", *EVAL[6:]]
    argv[argv.index("--methods") + 1] = methods
    check_argv(fuzz_base, baked, latlong_exr, argv, mention=["methods"], target="cli.pinned", tolerate=False)
