"""The README's first two commands stay true (issue 9, item 7: the install line ran
``apt-get install`` without ``apt-get update`` and found nothing on a machine with empty package
lists), and ``.ci/run`` runs the README's test command."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def _first_commands() -> list[str]:
    blocks = re.findall(r"```bash\n(.*?)\n```", (REPO / "README.md").read_text(), flags=re.S)
    return [b.strip() for b in blocks[:2]]


def test_install_line_updates_package_lists_before_installing():
    install = _first_commands()[0]
    steps = [s.strip() for s in install.split("&&")]
    update = next(i for i, s in enumerate(steps) if s.endswith("apt-get update"))
    install_step = next(i for i, s in enumerate(steps) if "apt-get install" in s)
    assert update < install_step
    for pkg in ("libegl1", "libegl-mesa0", "libgl1-mesa-dri", "openexr"):
        assert pkg in steps[install_step]
    assert steps[-1].startswith("envcap demo")


def test_ci_runs_the_readme_test_command_after_apt_get_update():
    ci = (REPO / ".ci" / "run").read_text()
    test_cmd = _first_commands()[1].split("&&")[-1].strip()
    assert test_cmd == "python3 -m pytest"
    assert ci.rstrip().splitlines()[-1].strip() == test_cmd
    assert ci.index("apt-get update") < ci.index("apt-get install")
    # every system package the README names is installed by CI too
    for pkg in re.findall(r"install -y ([^&]+)", _first_commands()[0])[0].split():
        assert pkg in ci
