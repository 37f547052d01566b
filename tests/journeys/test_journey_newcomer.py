"""A newcomer's first minutes, typed as a user types them: ``envcap demo``, then ``envcap view`` on
the demo's output as it is (the probe set in ``probes/``, the report in ``evaluation/``), the page
in a browser, then ``envcap evaluate`` on the demo's probe set.  Each command's output feeds the
next unchanged; small options keep the journey to ~15 s on 2 cores."""

import re

import numpy as np
import pytest

pytestmark = pytest.mark.slow   # a demo, a server, a page and an evaluation: ~15 s on 2 idle cores
PROBE_DOT = [255, 204, 51]      # the map's probe marker, #fc3


def test_demo_then_view_then_evaluate(terminal, chromium):
    out = terminal.run("envcap demo --out envcap-demo --resolution 8 --spacing 100").stdout
    assert "envcap view envcap-demo" in out   # the demo says what to type next
    assert (terminal.cwd / "envcap-demo" / "probes" / "probes_atlas.ktx2").is_file()

    port = terminal.free_port()
    viewer = terminal.start(f"envcap view envcap-demo --port {port}")
    try:
        line = terminal.first_line(viewer, "envcap viewer: ")
        url = line.split()[2]
        assert url == f"http://127.0.0.1:{port}/", line
        assert "report" in line and "evaluation" in line, line   # the demo's report found beside the probes
        chromium.errors.clear()
        chromium.goto(url)
        assert chromium.evaluate("window.envcap.ready.then(() => 'ok', e => 'error: ' + e.message)") == "ok", chromium.errors
        assert chromium.errors == []
        status = chromium.evaluate("document.getElementById('status').textContent")
        assert re.search(r"canyon: 1 street\(s\), \d+ probes, 8² faces", status), status
        cfg = chromium.evaluate("window.envcap.viewer.cfg")
        probe = cfg["streets"][0]["probes"][1]["position"]
        # probes drawn: on the map at their positions; the view has content; the report's plots shown
        dot = chromium.evaluate(f"(() => {{ const [u, v] = window.envcap.mapPoint({probe[0]}, {probe[2]});"
                                " return Array.from(document.getElementById('map').getContext('2d')"
                                ".getImageData(Math.round(u), Math.round(v), 1, 1).data.slice(0, 3)); })()")
        assert dot == PROBE_DOT, dot
        view = np.array(chromium.evaluate(
            "(() => { const c = document.getElementById('view'), g = document.createElement('canvas');"
            " g.width = c.width; g.height = c.height; const x = g.getContext('2d'); x.drawImage(c, 0, 0);"
            " return Array.from(x.getImageData(0, 0, c.width, c.height).data); })()"), np.float64).reshape(-1, 4)
        assert view[:, :3].std() > 10 and view[:, :3].mean() > 20, "the street view is empty"
        assert chromium.evaluate("document.querySelectorAll('#plots img').length") >= 3
        assert len(cfg["evaluation"]) > 0   # the report's positions on the map
    finally:
        viewer.terminate()
        viewer.wait(10)
        chromium.goto("about:blank")

    terminal.run("envcap evaluate canyon --probes envcap-demo/probes --out ev --positions 2 --resolution 8 "
                 "--methods nearest,planes_mip --lobes inf,16 --no-images")
    report = (terminal.cwd / "ev" / "report.md").read_text()
    assert "planes_mip" in report and "nearest" in report
