"""The viewer's server and ``envcap view``: loopback only, the page and the probe set's files
served, nothing else; the config carries the runtime uniforms of the numpy twin; the CLI prints
the address and serves it."""

import json
import shutil
import subprocess
import sys
import urllib.error
import urllib.request

import numpy as np
import pytest

from envcap.probeset.store import read_probe_set
from envcap.runtime.shader_targets import TARGETS
from envcap.runtime.street import RuntimeStreet
from envcap.viewer import ViewerServer, ViewerSite


def get(url):
    with urllib.request.urlopen(url, timeout=10) as r:
        return r.status, r.headers.get("Content-Type"), r.read()


def test_serves_page_probe_files_and_api(viewer_server, viewer_probe_dir):
    base = viewer_server.url
    assert base.startswith("http://127.0.0.1:")
    status, ctype, body = get(base)
    assert status == 200 and ctype.startswith("text/html") and b'src="web/viewer.js"' in body
    for name in ("viewer.js", "runtime.js", "ktx2.js", "viewer.css"):
        assert get(base + "web/" + name)[0] == 200
    assert get(base + "set/probes_atlas.ktx2")[2] == (viewer_probe_dir / "probes_atlas.ktx2").read_bytes()
    glsl = get(base + "api/runtime.glsl")[2].decode()
    assert glsl.startswith(TARGETS["webgl2"].version + "\n")
    assert not [ln for ln in glsl.splitlines() if ln.strip().startswith("#include")]
    assert "uniform EnvcapStreet envcap_street;" in glsl and "envcap_face_atlas_lod" in glsl


@pytest.mark.parametrize("path", ["/set/../manifest.json", "/set/%2e%2e/etc/passwd", "/web/../server.py",
                                  "/set/exr/probe_000.exr", "/etc/passwd", "/api/nothing"])
def test_nothing_else_is_served(viewer_server, path):
    with pytest.raises(urllib.error.HTTPError) as e:
        get(viewer_server.url.rstrip("/") + path)
    assert e.value.code == 404


def test_config_uniforms_are_the_runtime_streets(viewer_server, viewer_probe_dir):
    cfg = json.loads(get(viewer_server.url + "api/config.json")[2])
    ps = read_probe_set(viewer_probe_dir, distance=False)
    street = ps.manifest.streets[0]
    for planes in ("nominal", "fitted"):
        ref = RuntimeStreet.from_manifest(street, planes).uniforms(ps.manifest.lobes.powers)
        got = cfg["streets"][0]["uniforms"][planes]
        for name in ("along_s", "pos", "planes", "xk"):
            np.testing.assert_array_equal(np.float32(got[name]), np.asarray(getattr(ref, name)).ravel())
        assert (got["count"], got["along"], got["nlevels"]) == (ref.count, ref.along, ref.nlevels)
    assert cfg["sun"] == list(ps.manifest.sky.sun.direction)
    assert {m["name"] for m in cfg["methods"]} >= {"nearest", "planes", "planes_mip", "blend"}
    assert "depth_reproject" not in {m["name"] for m in cfg["methods"]}  # numpy only: no GLSL


def test_bad_inputs_are_named(tmp_path, canyon_probe_set, viewer_probe_dir):
    from envcap.probeset.store import write_probe_set

    with pytest.raises(FileNotFoundError, match="not found"):
        ViewerSite.open(tmp_path / "missing")
    plain = write_probe_set(tmp_path / "plain", canyon_probe_set, exr=False, previews=False, writers=["ktx2"])
    with pytest.raises(ValueError, match="no probes_atlas.ktx2, the WebGL2 face atlas"):
        ViewerSite.open(plain)
    with pytest.raises(FileNotFoundError, match="report.json"):
        ViewerSite.open(viewer_probe_dir, report_dir=tmp_path)
    site = ViewerSite.open(viewer_probe_dir)
    with pytest.raises(ValueError, match="loopback"):
        ViewerServer(site, host="0.0.0.0")


def test_cli_view_prints_the_address_and_serves(viewer_probe_dir):
    proc = subprocess.Popen([sys.executable, "-m", "envcap", "view", str(viewer_probe_dir)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.startswith("envcap viewer: http://127.0.0.1:"), line + proc.stderr.read()
        url = line.split()[2]
        assert json.loads(get(url + "api/config.json")[2])["resolution"] == 8
    finally:
        proc.terminate()
        proc.wait(10)


def test_report_plots_are_listed_and_served(tmp_path, viewer_probe_dir):
    from PIL import Image

    from envcap.viewer import serve

    rep = tmp_path / "report"
    rep.mkdir()
    rows = [{"street": "main", "method": m, "lobe_power": w, "rel_rmse": e, "position": [10.0, 2.0, 1.5]}
            for m, w, e in (("nearest", None, 0.3), ("nearest", 16.0, 0.1), ("planes_mip", None, 0.05))]
    rows += [{"street": "main", "method": "nearest", "rel_rmse": float("nan"), "position": [0.0, 2.0, 0.0]},
             {"street": "main", "method": "nearest", "rel_rmse": 0.2, "position": "bad"}]
    (rep / "report.json").write_text(json.dumps({"positions": rows}) + "\n")
    for name in ("worst_canyon_0_mirror.png", "error_vs_lobe.png"):
        Image.new("RGB", (4, 3), (200, 10, 10)).save(rep / name)
    (rep / "notes.txt").write_text("not served\n")
    site = ViewerSite.open(viewer_probe_dir, report_dir=rep)
    assert site.config()["plots"] == ["report/error_vs_lobe.png", "report/worst_canyon_0_mirror.png"]
    # evaluation positions: grouped by position, mean over lobe powers; NaN and malformed rows dropped
    ev = site.config()["evaluation"]
    assert len(ev) == 1 and ev[0]["position"] == [10.0, 2.0, 1.5]
    assert ev[0]["error"] == pytest.approx({"nearest": 0.2, "planes_mip": 0.05})
    server, thread = serve(site)
    try:
        status, ctype, body = get(server.url + "report/error_vs_lobe.png")
        assert status == 200 and ctype == "image/png" and body == (rep / "error_vs_lobe.png").read_bytes()
        with pytest.raises(urllib.error.HTTPError):
            get(server.url + "report/notes.txt")
    finally:
        server.shutdown()
        server.server_close()


def test_view_finds_the_set_in_a_demo_directory_and_names_the_atlas_command(tmp_path, canyon_probe_set, viewer_probe_dir):
    """``envcap view`` on ``envcap demo``'s output (``probes/`` + ``evaluation/``) serves the set
    with its report; on a set without the face atlas it prints the one command that makes it."""
    from envcap.viewer.site_dir import open_site

    top = tmp_path / "envcap-demo"
    shutil.copytree(viewer_probe_dir, top / "probes")
    (top / "evaluation").mkdir()
    (top / "evaluation" / "report.json").write_text(json.dumps({"positions": []}) + "\n")
    site = open_site(top)
    assert site.probe_dir == (top / "probes").resolve() and site.report_dir == (top / "evaluation").resolve()
    shutil.copytree(viewer_probe_dir, top / "more")
    with pytest.raises(ValueError, match="holds 2 probe sets"):
        open_site(top)
    with pytest.raises(FileNotFoundError, match="no probe set here"):
        open_site(top / "evaluation")
    plain = tmp_path / "plain set"
    from envcap.probeset.store import write_probe_set

    write_probe_set(plain, canyon_probe_set, exr=False, previews=False, writers=["ktx2"])
    r = subprocess.run([sys.executable, "-m", "envcap", "view", "plain set"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=60)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("envcap: error: ") and "no probes_atlas.ktx2" in lines[0]
    assert "make it with: envcap export web 'plain set' --out 'plain set-web'" in lines[0], lines[0]
