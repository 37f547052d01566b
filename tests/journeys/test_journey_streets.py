"""Journey: a user finds the streets of a city with ``envcap streets``, then bakes and evaluates the
scene it wrote, each output typed into the next command unchanged, in a fresh working directory;
once from the generated city's mesh file, once from a bundled scene name."""

from __future__ import annotations

import json
import shlex
import tomllib
from pathlib import Path
from typing import Any

import pytest

CITY_XML = Path(__file__).resolve().parents[2] / "city_scenes" / "generated_city" / "data" / "city.xml"
Terminal = Any
"""The ``terminal`` fixture's type (tests/journeys/conftest.py; not imported: ``conftest`` names two modules)."""


def _evaluated_streets(terminal: Terminal, report: str) -> set[str]:
    rows = json.loads((terminal.cwd / report / "report.json").read_text())["positions"]
    return {r["street"] for r in rows}


@pytest.mark.slow
def test_streets_of_a_mesh_file_captured_and_evaluated(terminal: Terminal) -> None:
    found = terminal.run(f"envcap streets {shlex.quote(str(CITY_XML))} --up-axis z --offset -512000 0 5403000 "
                         f"--out streets")
    assert "11 streets, 6 intersections" in found.stdout
    assert "progress: import:" in found.stderr and "Traceback" not in found.stderr
    scene = tomllib.loads((terminal.cwd / "streets" / "scene.toml").read_text())
    assert scene["ground"] == {"enabled": False} and len(scene["streets"]) == 11

    bake = terminal.run("envcap capture streets/scene.toml --out probes --resolution 16 --spacing 40 --quiet")
    assert "z-fight" not in bake.stderr and "wrote" in bake.stdout
    terminal.run("envcap evaluate streets/scene.toml --probes probes --out eval --positions 2 --resolution 16 "
                 "--methods nearest,planes_mip --lobes 64 --no-images")
    assert _evaluated_streets(terminal, "eval") == {s["name"] for s in scene["streets"]}


@pytest.mark.slow
def test_streets_of_a_bundled_scene_captured_and_evaluated(terminal: Terminal) -> None:
    found = terminal.run("envcap streets canyon --out s2")
    assert "1 streets, 0 intersections" in found.stdout
    assert tomllib.loads((terminal.cwd / "s2" / "scene.toml").read_text())["mesh"] == [{"scene": "canyon"}]
    terminal.run("envcap capture s2/scene.toml --out p2 --resolution 16 --spacing 100 --quiet")
    terminal.run("envcap evaluate s2/scene.toml --probes p2 --out e2 --positions 2 --resolution 16 "
                 "--methods nearest,planes_mip --lobes 64 --no-images")
    assert _evaluated_streets(terminal, "e2") == {"street_00"}
