"""The known-issue registry and the pinned tests agree: each known issue has exactly one strict
xfail test, and each such test names a known issue."""

import re
from pathlib import Path

from fuzz_known import KNOWN


def test_each_known_issue_has_one_pinned_strict_xfail_test():
    text = "\n".join(p.read_text() for p in sorted(Path(__file__).parent.glob("test_fuzz_*.py")))
    marks = re.findall(r'@pytest\.mark\.xfail\(strict=True, reason="issue 9: ([\w-]+)"\)', text)
    assert sorted(marks) == sorted(KNOWN), (sorted(marks), sorted(KNOWN))
    for k in KNOWN.values():
        assert k.summary and k.fix and k.targets
