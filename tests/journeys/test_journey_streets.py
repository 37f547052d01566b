"""Journey: a user finds the streets of a city with ``envcap streets``, then bakes and evaluates the
scene it wrote, each output typed into the next command unchanged, in a fresh working directory;
once from the generated city's mesh file (then ``envcap view`` shows the probe set and the report
in a browser), once from a bundled scene name."""

from __future__ import annotations

import json
import re
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


PROBE_DOT = [255, 204, 51]      # the viewer map's probe marker, #fc3


def _viewed(terminal: Terminal, chromium: Any, probes: str, report: str) -> dict[str, Any]:
    """``envcap view PROBES --report REPORT`` in the background, its page loaded in ``chromium``:
    the page's status line, its config and, per street, how many of its probes the map shows."""
    port = terminal.free_port()
    viewer = terminal.start(f"envcap view {probes} --report {report} --port {port}")
    try:
        line = terminal.first_line(viewer, "envcap viewer: ")
        url = line.split()[2]
        assert url == f"http://127.0.0.1:{port}/" and f"report {terminal.cwd / report}" in line, line
        chromium.errors.clear()
        chromium.goto(url)
        assert chromium.evaluate("window.envcap.ready.then(() => 'ok', e => 'error: ' + e.message)") == "ok", \
            chromium.errors
        assert chromium.errors == []
        cfg = chromium.evaluate("window.envcap.viewer.cfg")
        # per street, how many of its probes show the map's probe marker (evaluation dots drawn over some)
        dots = chromium.evaluate(
            "(() => { const m = document.getElementById('map').getContext('2d'); return window.envcap.viewer.cfg"
            ".streets.map(s => s.probes.filter(p => { const [u, v] = window.envcap.mapPoint(p.position[0],"
            " p.position[2]); const d = m.getImageData(Math.round(u), Math.round(v), 1, 1).data;"
            f" return d[0] === {PROBE_DOT[0]} && d[1] === {PROBE_DOT[1]} && d[2] === {PROBE_DOT[2]}; }}).length); }})()")
        return {"status": chromium.evaluate("document.getElementById('status').textContent"), "cfg": cfg,
                "dots": dots}
    finally:
        viewer.terminate()
        viewer.wait(10)
        chromium.goto("about:blank")


@pytest.mark.slow
def test_streets_of_a_mesh_file_captured_evaluated_and_viewed(terminal: Terminal, chromium: Any) -> None:
    found = terminal.run(f"envcap streets {shlex.quote(str(CITY_XML))} --up-axis z --offset -512000 0 5403000 "
                         f"--out streets")
    assert "11 streets, 6 intersections" in found.stdout
    assert "progress: import:" in found.stderr and "Traceback" not in found.stderr
    scene = tomllib.loads((terminal.cwd / "streets" / "scene.toml").read_text())
    assert scene["ground"] == {"enabled": False} and len(scene["streets"]) == 11

    bake = terminal.run("envcap capture streets/scene.toml --out probes --resolution 16 --spacing 40 --quiet --webgl2")
    assert "z-fight" not in bake.stderr
    wrote = re.search(r"wrote (\d+) probes \(16\^2 x 6, \d+ levels\) of '(\w+)'", bake.stdout)
    assert wrote, bake.stdout
    terminal.run("envcap evaluate streets/scene.toml --probes probes --out eval --positions 2 --resolution 16 "
                 "--methods nearest,planes_mip --lobes 64 --no-images")
    assert _evaluated_streets(terminal, "eval") == {s["name"] for s in scene["streets"]}

    page = _viewed(terminal, chromium, "probes", "eval")
    count, name = wrote.groups()
    assert page["status"].startswith(f"{name}: 11 street(s), {count} probes, 16² faces"), page["status"]
    assert [s["name"] for s in page["cfg"]["streets"]] == [s["name"] for s in scene["streets"]]
    assert min(page["dots"]) >= 1, page["dots"]                # every street's probes on the map
    assert len(page["cfg"]["evaluation"]) == 2 * 11            # the report's positions, 2 per street


@pytest.mark.slow
def test_streets_of_a_bundled_scene_captured_and_evaluated(terminal: Terminal) -> None:
    found = terminal.run("envcap streets canyon --out s2")
    assert "1 streets, 0 intersections" in found.stdout
    assert tomllib.loads((terminal.cwd / "s2" / "scene.toml").read_text())["mesh"] == [{"scene": "canyon"}]
    terminal.run("envcap capture s2/scene.toml --out p2 --resolution 16 --spacing 100 --quiet")
    terminal.run("envcap evaluate s2/scene.toml --probes p2 --out e2 --positions 2 --resolution 16 "
                 "--methods nearest,planes_mip --lobes 64 --no-images")
    assert _evaluated_streets(terminal, "e2") == {"street_00"}
