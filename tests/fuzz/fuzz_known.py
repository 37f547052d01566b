"""Known issue-9 failures that the fuzz suite finds today, each with its pinned xfail test.

A generated case whose violations all match a known issue is counted (``known:<id>`` in the
figures) and tolerated by the general fuzz tests; the issue's pinned test
(``@pytest.mark.xfail(strict=True, reason="issue 9: <id>")``) fails on its reproducer until the
fix lands, then passes and so breaks the run (strict).  When that happens, delete the xfail mark
and the entry here: from then on the general fuzz tests fail on any such case.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fuzz_harness import Outcome


@dataclass(frozen=True)
class Known:
    id: str
    summary: str
    fix: str  # the module / function that probably needs the fix
    targets: tuple[str, ...]
    match: Callable[[Any, Outcome], bool]


def _heads(res: Outcome) -> set[str]:
    return {p.split(":", 1)[0] for p in res.problems}


def _opt(argv: Any, name: str) -> float | None:
    """The number after option ``name`` in a generated argv, if there is one."""
    if not isinstance(argv, list) or name not in argv or argv.index(name) + 1 >= len(argv):
        return None
    try:
        return float(argv[argv.index(name) + 1])
    except ValueError:
        return None


def _runaway_or_memory(res: Outcome) -> bool:
    return _heads(res) <= {"runaway", "traceback"} and (res.kind == "runaway" or res.exc_type == "MemoryError")


def _message_only(res: Outcome, *words: str) -> bool:
    return _heads(res) == {"message"} and any(w in res.message for w in words)


def _huge_positions(argv: Any) -> bool:
    v = _opt(argv, "--positions")
    return v is not None and v > 1e6


def _texels(case: Any) -> str:
    return case.get("texels", "") if isinstance(case, dict) else ""


_ALL = [
    Known("cli-positions-bound", "evaluate --positions 100000000 runs away (no bound before work)",
          "envcap/evaluate/sweep.py: sample_positions / envcap/cli/evaluate.py (bound the sweep before work)",
          ("cli.evaluate", "cli.any"),
          lambda argv, res: _runaway_or_memory(res) and _huge_positions(argv)),
    Known("cli-seed-message", "--seed -1: 'expected non-negative integer' does not name --seed",
          "envcap/cli/evaluate.py: run (check --seed and name it) or envcap/evaluate/sweep.py: Sweep",
          ("cli.evaluate",),
          lambda argv, res: _message_only(res, "non-negative integer")),
    Known("cli-huge-int-message", "evaluate --resolution 99999999999999999999: 'Maximum allowed size exceeded' "
          "(numpy's words) names neither the option nor the cost (capture's is bounded now)",
          "envcap/core/budget.py (check sizes before numpy sees them) / envcap/evaluate (truth capture size)",
          ("cli.evaluate", "cli.any"),
          lambda argv, res: _message_only(res, "Maximum allowed size exceeded")),
    Known("cli-methods-message", "evaluate --methods '': 'unknown or no method(s) []' does not name --methods",
          "envcap/cli/evaluate.py: run (name the option in the message)",
          ("cli.evaluate",),
          lambda argv, res: _message_only(res, "unknown or no method")),
    Known("exr-negative", "read_exr_cube accepts a cube EXR with negative RGB or Z texels (envcap prefilter "
          "and read_probe_set now check them themselves; the reader, the door both use, does not)",
          "envcap/formats/exr_cube.py: read_exr_cube (reject RGB < 0 and Z < 0, naming the file)",
          ("read.exr", "cli.prefilter_input"),
          lambda case, res: _heads(res) == {"wrong"} and "negative" in res.problems[0]),
    Known("exr-header-utf8", "a header attribute name or type with a non-UTF-8 byte: read_exr_cube raises "
          "UnicodeDecodeError \"'utf-8' codec can't decode byte 0x80 ...\", naming no file",
          "envcap/formats/exr_cube.py: read_exr_cube (wrap the binding's UnicodeDecodeError with the path)",
          ("read.exr",),
          lambda case, res: _message_only(res, "codec can't decode")),
    Known("runtime-nan-texture", "the numpy twin's lookup turns NaN / Inf texels into NaN radiance silently "
          "(design question: the twin mirrors GLSL, which cannot raise)",
          "envcap/runtime/chains.py: ProbeChains (check levels) and envcap/runtime/sampling.py: sample_street "
          "(check sky levels), or document that textures are checked when read",
          ("runtime.lookup",),
          lambda case, res: _texels(case) in ("nan_probe", "nan_sky", "inf_sky") and _heads(res) == {"nonfinite"}),
]

KNOWN: dict[str, Known] = {k.id: k for k in _ALL}


def known_issue(target: str, case: Any, res: Outcome) -> str | None:
    """Id of the known issue that explains every violation of ``res``, or ``None``."""
    for k in KNOWN.values():
        if target in k.targets and k.match(case, res):
            return k.id
    return None
