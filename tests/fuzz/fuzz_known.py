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


def _message_only(res: Outcome, *words: str) -> bool:
    return _heads(res) == {"message"} and any(w in res.message for w in words)


_ALL = [
]

KNOWN: dict[str, Known] = {k.id: k for k in _ALL}


def known_issue(target: str, case: Any, res: Outcome) -> str | None:
    """Id of the known issue that explains every violation of ``res``, or ``None``."""
    for k in KNOWN.values():
        if target in k.targets and k.match(case, res):
            return k.id
    return None
