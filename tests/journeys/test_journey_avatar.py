"""Journey: a user brings a skinned glTF avatar, computes its proxy spheres and per-vertex blockers
with ``envcap avatar``, and evaluates the dynamic terms of crowds of that avatar in a street with
``envcap evaluate --occluders avatars --avatar FILE``: the file ``envcap avatar`` wrote is the one
the evaluation reads, unchanged, in a fresh working directory.

The user's avatar is the test avatar ``walker`` written by the test
(:func:`envcap.dynamic.avatar_synthetic.write_walker`), as a user's own file.  That the crowds are
that file's (and the walker through ``envcap avatar`` evaluates exactly as the bundled default)
is checked in ``tests/evaluate/test_dynamic_avatars.py``; here: each output feeds the next, the
spheres the evaluation used are those ``envcap avatar`` printed, and the avatars hid sky in the
truth captures."""

from __future__ import annotations

import json
import re
from collections import defaultdict
from typing import Any

import pytest

from envcap.dynamic.avatar_synthetic import write_walker

pytestmark = pytest.mark.slow   # an avatar, a small bake and 7 crowds x 2 positions of captures: ~20 s on 2 cores
Terminal = Any
"""The ``terminal`` fixture's type (tests/journeys/conftest.py)."""


def test_avatar_then_evaluate_crowds_of_it(terminal: Terminal) -> None:
    write_walker(terminal.cwd / "my_walker.glb")     # the user's skinned avatar

    made = terminal.run("envcap avatar my_walker.glb --out my_walker_envcap.glb").stdout
    assert made.startswith(f"{terminal.cwd / 'my_walker_envcap.glb'}: 982 vertices, 11 joints, 5 keyframes (mean), "
                           "_ENVCAP_BLOCKERS k=4"), made
    printed = [float(r) for r in re.findall(r"sphere radius ([0-9.]+) m", made)]
    assert len(printed) == 11

    terminal.run("envcap capture canyon --out probes --resolution 8 --spacing 100 --quiet")
    terminal.run("envcap evaluate canyon --probes probes --out eval --positions 1 --resolution 8 --methods nearest "
                 "--lobes 16 --no-images --occluders avatars --avatar my_walker_envcap.glb")

    report = (terminal.cwd / "eval" / "report.md").read_text()
    assert "### canyon: crowds of my_walker_envcap.glb (2 positions, 8² truth)" in report, report[-2000:]
    (result,) = json.loads((terminal.cwd / "eval" / "occluders.json").read_text())
    assert result["avatar"]["file"] == "my_walker_envcap.glb" and result["avatar"]["joints"] == 11
    assert [round(r, 3) for r in result["avatar"]["sphere_radii"]] == printed   # the spheres envcap avatar wrote
    crowds: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for row in result["avatars"]:
        crowds[row["ring"]].append(row)
    assert len(crowds) == 7
    for ring, rows in crowds.items():
        for r in rows:   # the crowd LOD: near avatars as their 11 bone spheres, far ones as one sphere each
            assert r["spheres"] == 11 * r["near"] + (r["avatars"] - r["near"]), (ring, r)
    assert {r["near"] for r in crowds["10 at 4.5 m"]} == {0} and {r["near"] for r in crowds["6 at 0.6 m"]} == {6}
    # the avatars stood in the truth captures: they hid sky, and the occluder-free capture is off there
    hiding = [r for r in result["avatars"] if r["sky_hidden"] > 0.02]
    assert hiding, "the avatars hid no sky"
    assert all(r["rel_err"] > 0 for r in hiding if r["variant"] == "oracle")
