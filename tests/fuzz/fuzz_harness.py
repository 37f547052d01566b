"""The fuzzing property and its bookkeeping: run one generated case, judge it, count it.

The property (issue 9): a case either succeeds with finite output, or fails with one line that
names the problem (in-process: an exception of ``envcap.cli.USER_ERRORS``, which the CLI prints
as ``envcap: error: ...`` with exit status 2); never a traceback (any other exception type),
never a runaway (past ``timeout`` seconds or ``mem`` bytes of new address space), never a
leftover (nothing new remains after a failure; after a success only the output is new), and
never a lost file (an input, the working directory or a directory envcap did not write is left
as it was).

Each case runs in its own sandbox (:mod:`fuzz_sandbox`), so leftovers and losses are seen by
comparing two snapshots of it; runaways are cut there too.

Settings: ``ENVCAP_FUZZ_EXAMPLES=N`` runs N generated cases per test (the default run is short);
``ENVCAP_FUZZ_RANDOM=1`` draws fresh cases (reproduce with pytest's ``--hypothesis-seed``), else
every run draws the same cases; ``ENVCAP_FUZZ_DISCOVER=FILE.jsonl`` records every property
violation there instead of failing (to catalog failures); ``ENVCAP_FUZZ_FIGURES=FILE.json``
writes the per-target counts at the end of the session.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import time
import traceback
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from fuzz_sandbox import Runaway, Sandbox, guard, inside, snapshot
from hypothesis import HealthCheck, settings

from envcap.cli import USER_ERRORS

REPO = Path(__file__).resolve().parents[2]

EXAMPLES = int(os.environ.get("ENVCAP_FUZZ_EXAMPLES", "0") or 0)
RANDOM = os.environ.get("ENVCAP_FUZZ_RANDOM", "") not in ("", "0")
DISCOVER = os.environ.get("ENVCAP_FUZZ_DISCOVER", "")

CASE_TIMEOUT_S = 10.0
"""Default wall-clock limit of one case (s); past it the case is a runaway."""
CASE_MEMORY = 1536 << 20
"""Default limit of new address space for one case (bytes); past it allocation fails (MemoryError)."""

TALLY: dict[str, Counter] = defaultdict(Counter)
"""Per target: cases, ok, user_error, and each kind of violation (traceback, runaway, leftover, lost, ...)."""
SECONDS: dict[str, float] = defaultdict(float)
"""Per target: wall-clock seconds spent running cases (generation and judging excluded)."""


def fuzz_settings(default_examples: int, **overrides: Any) -> settings:
    """Hypothesis settings of a fuzz test: ``default_examples`` cases (or ENVCAP_FUZZ_EXAMPLES),
    no deadline, the same cases every run unless ENVCAP_FUZZ_RANDOM, no example database."""
    kw: dict[str, Any] = {
        "max_examples": EXAMPLES or default_examples,
        "deadline": None,
        "derandomize": not RANDOM,
        "database": None,
        "suppress_health_check": list(HealthCheck),
        "print_blob": True,
    }
    kw.update(overrides)
    return settings(**kw)


PINNED = settings(max_examples=5, deadline=None, derandomize=True, database=None,
                  suppress_health_check=list(HealthCheck), print_blob=True)
"""Settings of a pinned known-issue test: its ``@example`` reproducers run first (a failing one
fails the test at once), then a few generated cases near them."""


# --------------------------------------------------------------------------------------------
# Outcomes


@dataclass
class Outcome:
    """What one case did, and every way in which it broke the property."""

    kind: str  # "ok", "user_error", "traceback", "runaway", "exit" (a CLI status other than 0 / 2)
    message: str = ""  # the error line (user_error), the traceback head (traceback)
    value: Any = None  # the return value (ok) or the exception
    stderr: str = ""
    stdout: str = ""
    seconds: float = 0.0
    problems: list[str] = field(default_factory=list)
    exc_type: str = ""
    where: str = ""  # last envcap frame of a traceback: "envcap/x/y.py:function"

    @property
    def ok(self) -> bool:
        return self.kind == "ok"

    def violate(self, what: str) -> None:
        self.problems.append(what)

    def signature(self) -> str:
        """Short text that tells distinct failures apart (for the catalog)."""
        heads = sorted({p.split(":", 1)[0] for p in self.problems})
        return f"{'+'.join(heads)} {self.exc_type} {self.where}".strip()

    def describe(self) -> str:
        lines = [f"kind {self.kind} ({self.seconds:.2f} s)", *[f"  - {p}" for p in self.problems]]
        if self.stderr.strip():
            lines.append("stderr (last lines):")
            lines += ["  | " + ln for ln in self.stderr.strip().splitlines()[-8:]]
        return "\n".join(lines)


def _envcap_frame(tb: Any) -> str:
    frames = [f for f in traceback.extract_tb(tb) if "/envcap/" in f.filename.replace(os.sep, "/")]
    if not frames:
        return ""
    f = frames[-1]
    rel = f.filename.replace(os.sep, "/").split("/envcap/", 1)[1]
    return f"envcap/{rel}:{f.name}"


def _exc_head(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"[:300]


def run_case(sb: Sandbox, fn: Callable[[], Any], *, out: Path | None = None, inputs: Iterable[Path] = (),
             cli: bool = False, timeout: float = CASE_TIMEOUT_S, mem: int = CASE_MEMORY) -> Outcome:
    """Run ``fn()`` in ``sb`` under the guards and judge everything but the output values.

    ``cli``: ``fn`` is ``envcap.cli.main(argv)``: status 0 = success, 2 = user error (stderr must
    hold exactly one ``error:`` line, the last, from envcap or argparse), anything else or an
    escaping exception is a violation.  Otherwise: a return is a success, an exception of
    ``USER_ERRORS`` a user error (its message must be one non-empty line), any other a traceback.
    ``out``: the output path of the case (new files there are expected after a success);
    ``inputs``: files and directories the case reads (they must survive whatever happens).
    """
    before = snapshot(sb.root)
    out_before = _is_envcap_output(out) if out is not None else False
    err, std = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    res = Outcome("ok")
    with inside(sb):
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std), guard(timeout, mem):
                try:
                    value = fn()
                except SystemExit as e:  # argparse
                    value = e.code if isinstance(e.code, int) else 2
            res.value = value
        except Runaway as e:
            res = Outcome("runaway", message=str(e), exc_type="Runaway", where=_envcap_frame(e.__traceback__))
            res.violate(f"runaway: {e} (in {res.where or '?'})")
        except USER_ERRORS as e:
            if cli:  # main() itself catches these: one escaping main is a bug
                res = Outcome("traceback", message=_exc_head(e), value=e, exc_type=type(e).__name__,
                              where=_envcap_frame(e.__traceback__))
                res.violate(f"traceback: {res.message} escaped main() (in {res.where or '?'})")
            else:
                res = Outcome("user_error", message=str(e) if not isinstance(e, KeyError) else f"missing key {e}",
                              value=e, exc_type=type(e).__name__, where=_envcap_frame(e.__traceback__))
        except KeyboardInterrupt:
            raise
        except BaseException as e:  # noqa: BLE001 - this is what the property forbids
            res = Outcome("traceback", message=_exc_head(e), value=e, exc_type=type(e).__name__,
                          where=_envcap_frame(e.__traceback__))
            res.violate(f"traceback: {res.message} (in {res.where or '?'})")
    res.seconds = time.perf_counter() - t0
    res.stderr, res.stdout = err.getvalue(), std.getvalue()
    if cli and res.kind == "ok":
        _judge_status(res)
    if res.kind == "user_error":
        _judge_message(res)
    after = snapshot(sb.root)
    _judge_files(res, sb, before, after, out, out_before, [Path(p) for p in inputs])
    return res


ERROR_LINE = re.compile(r"^envcap(?: [\w-]+)?: error: \S")


def _judge_status(res: Outcome) -> None:
    status = res.value
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    if status == 0:
        return
    if status != 2:
        res.kind = "exit"
        res.violate(f"exit: status {status!r} (expected 0 or 2)")
        return
    res.kind = "user_error"
    if not lines and res.stdout.lstrip().startswith("usage:"):  # no command: the help, status 2
        res.message = "no command (help printed)"
        return
    errors = [ln for ln in lines if "error:" in ln]
    res.message = errors[-1].split("error:", 1)[1].strip() if errors else ""
    if any(ln.startswith("Traceback") for ln in lines):
        res.violate("traceback: printed on stderr")
    if len(errors) != 1 or not lines or lines[-1] is not errors[0] or not ERROR_LINE.match(errors[0]):
        res.violate(f"message: stderr must end in exactly one 'envcap: error: ...' line, got {lines[-4:]!r}")


def _judge_message(res: Outcome) -> None:
    msg = res.message
    if not msg.strip():
        res.violate(f"message: empty {res.exc_type} message")
    elif len(msg.strip().splitlines()) != 1:
        res.violate(f"message: {len(msg.strip().splitlines())} lines ({msg.strip().splitlines()[:3]!r})")


def _is_envcap_output(path: Path | None) -> bool:
    """Whether ``path`` is a directory an earlier envcap run wrote (probe set, chain, report)."""
    if path is None or not path.is_dir():
        return False
    return any((path / n).is_file() for n in (".envcap-output", "manifest.json", "chain.json", "report.md"))


def _under(rel: str, base: str) -> bool:
    return base in ("", ".") or rel == base or rel.startswith(base + os.sep)


def _judge_files(res: Outcome, sb: Sandbox, before: dict[str, str], after: dict[str, str], out: Path | None,
                 out_before: bool, inputs: list[Path]) -> None:
    root = sb.root.resolve()

    def rel(p: Path) -> str | None:
        try:
            return str((p if p.is_absolute() else sb.work / p).resolve().relative_to(root))
        except ValueError:
            return None

    out_rel = rel(out) if out is not None else None
    input_rels = [r for r in (rel(p) for p in inputs) if r is not None]
    work_rel = "work"
    # the output may be replaced only if it did not exist or envcap wrote it, and it is no input,
    # holds no input and is not the working directory (nor above it)
    replaceable = (out_rel is not None and res.ok
                   and (out_before or not any(_under(k, out_rel) and k != out_rel for k in before))
                   and not any(_under(i, out_rel) for i in input_rels)
                   and not _under(work_rel, out_rel))
    lost = [k for k, v in before.items()
            if after.get(k) != v and not (replaceable and _under(k, out_rel))]
    if lost:
        res.violate(f"lost: {len(lost)} pre-existing path(s) changed or gone: {sorted(lost)[:4]}")
    new = [k for k in after if k not in before]
    if res.ok and out_rel is not None:  # the output, and the folders made to hold it
        stray = [k for k in new if not _under(k, out_rel) and not _under(out_rel, k)]
    elif res.ok:
        stray = []
    else:
        stray = new
    temp_like = [k for k in new if re.search(r"(^|/)\.[^/]*\.(tmp|old)-", k)]
    leftovers = sorted(set(stray) | set(temp_like))
    if leftovers:
        res.violate(f"leftover: {len(leftovers)} new path(s) remain: {leftovers[:4]}")


# --------------------------------------------------------------------------------------------
# Finite outputs


def nonfinite(value: Any, what: str = "output", limit: float = float(np.finfo(np.float32).max)) -> str | None:
    """Where ``value`` (nested lists, dicts, dataclass fields, arrays, numbers) holds NaN, Inf or a
    magnitude past ``limit`` (float32's range by default); ``None`` when everything is finite."""
    stack: list[tuple[str, Any]] = [(what, value)]
    while stack:
        name, v = stack.pop()
        if isinstance(v, bool) or v is None or isinstance(v, (str, bytes)):
            continue
        if isinstance(v, (int, float, np.number)):
            x = float(v) if not isinstance(v, int) or abs(v) < 1 << 1000 else math.inf
            if not math.isfinite(x) or abs(x) > limit:
                return f"{name} = {v!r}"
            continue
        if isinstance(v, np.ndarray):
            if v.dtype.kind in "fc" or v.dtype.kind in "iu":
                a = v.astype(np.float64, copy=False) if v.dtype.kind != "c" else np.abs(v)
                bad = ~np.isfinite(a) | (np.abs(a) > limit)
                if np.any(bad):
                    idx = tuple(int(i) for i in np.argwhere(bad)[0])
                    return f"{name}{list(idx)} = {v[idx]!r} ({int(bad.sum())} of {v.size})"
            continue
        if isinstance(v, dict):
            stack += [(f"{name}.{k}", x) for k, x in v.items()]
        elif isinstance(v, (list, tuple)):
            stack += [(f"{name}[{i}]", x) for i, x in enumerate(v)]
        elif hasattr(v, "__dataclass_fields__"):
            stack += [(f"{name}.{k}", getattr(v, k)) for k in v.__dataclass_fields__]
    return None


def require_finite(res: Outcome, value: Any, what: str = "output", limit: float = float(np.finfo(np.float32).max)) -> None:
    bad = nonfinite(value, what, limit)
    if bad:
        res.violate(f"nonfinite: {bad}")


def require_names(res: Outcome, *names: str) -> None:
    """A user error must name at least one of ``names`` (an option, a key, a file; case-insensitive)."""
    if res.kind != "user_error" or not names:
        return
    msg = res.message.lower()
    if not any(n.lower() in msg for n in names if n):
        res.violate(f"message: names none of {list(names)}: {res.message[:200]!r}")


# --------------------------------------------------------------------------------------------
# Settling a case: count it, accept it, tolerate a known issue, or fail


def settle(target: str, case: Any, res: Outcome, *, known: Callable[[str, Any, Outcome], str | None] | None = None) -> None:
    """Count ``res`` under ``target`` and fail the test on a violation.

    ``known(target, case, res)`` may name a known issue (``fuzz_known.KNOWN``) that the violation
    matches: it is then counted as ``known:<id>`` and tolerated (its pinned xfail test covers it).
    With ENVCAP_FUZZ_DISCOVER every violation is recorded in that file and nothing fails.
    """
    t = TALLY[target]
    t["cases"] += 1
    SECONDS[target] += res.seconds
    t[res.kind] += 1
    for p in {p.split(":", 1)[0] for p in res.problems}:
        t[p] += 1
    if not res.problems:
        return
    kid = known(target, case, res) if known is not None else None
    if kid:
        t[f"known:{kid}"] += 1
    if DISCOVER:
        with open(DISCOVER, "a") as f:
            f.write(json.dumps({"target": target, "case": repr(case)[:2000], "kind": res.kind,
                                "problems": res.problems, "message": res.message[:500], "exc_type": res.exc_type,
                                "where": res.where, "signature": res.signature(), "known": kid,
                                "stderr": res.stderr[-1500:]}) + "\n")
        return
    if kid:
        return
    raise AssertionError(f"fuzz property broken ({target}):\ncase: {case!r}\n{res.describe()}")


def figures() -> dict[str, dict[str, Any]]:
    """Per target: the counts of :data:`TALLY` and the seconds spent."""
    return {t: {**dict(sorted(c.items())), "seconds": round(SECONDS[t], 2)} for t, c in sorted(TALLY.items())}
