"""``envcap export TARGET DIR --out OUT`` (docs/engines.md, section 7): the ``web`` target writes the
site ``envcap view`` serves as static files, making the WebGL2 face atlas of a set baked without
it (byte-identical to the bake's own writer); bad input is one line and leaves nothing; a target
registered from this file alone is found by the command (docs/architecture.md, "Where to add")."""

import json
import shutil

import pytest
from envcap_process import error_lines, run_envcap, tree_bytes

from envcap.cli import main
from envcap.export import ExportTarget, register_target, unregister_target
from envcap.outputs import MARKER_NAME
from envcap.probeset.store import read_probe_set, write_probe_set
from envcap.viewer.site import ViewerSite
from envcap.viewer.site_dir import open_site


@pytest.fixture(scope="module")
def sets(canyon_probe_set, tmp_path_factory):
    """The session canyon written twice: without the face atlas (``plain``) and with it (``atlas``)."""
    root = tmp_path_factory.mktemp("export")
    plain = write_probe_set(root / "plain", canyon_probe_set, exr=True, previews=False, writers=["ktx2", "exr"])
    atlas = write_probe_set(root / "atlas", canyon_probe_set, exr=False, previews=False, writers=["ktx2", "webgl2"])
    return plain, atlas


def test_web_export_is_the_viewers_site_with_the_atlas_made(sets, tmp_path, capsys):
    plain, atlas = sets
    out = tmp_path / "site"
    assert main(["export", "web", str(plain), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"python3 -m http.server 8000 --directory {out}" in printed
    # the atlas made from probes.ktx2 is the bake's writer's, byte for byte
    assert (out / "set" / "probes_atlas.ktx2").read_bytes() == (atlas / "probes_atlas.ktx2").read_bytes()
    for name in ("probes.ktx2", "sky.ktx2"):
        assert (out / "set" / name).read_bytes() == (plain / name).read_bytes()
    # set/ keeps a probe set, with just the web's files listed (the EXRs stay behind)
    files = json.loads((out / "set" / "manifest.json").read_text())["files"]
    assert files == {"probes": "probes.ktx2", "sky": "sky.ktx2", "probes_atlas": "probes_atlas.ktx2"}
    assert not (out / "set" / "exr").exists()
    assert read_probe_set(out / "set", distance=False).layer_count == 6
    # the page's config and runtime are the viewer's for the same set with its atlas
    served = ViewerSite.open(atlas)
    assert json.loads((out / "api" / "config.json").read_text()) == json.loads(json.dumps(served.config()))
    assert (out / "api" / "runtime.glsl").read_bytes() == served.routes()["/api/runtime.glsl"]()
    for page in ("index.html", "three.html", "web/viewer.js", "web/three_probes.js", "web/three_example.js",
                 "three/three.module.js", "three/three.core.js", "three/three.LICENSE", "README.md"):
        assert (out / page).is_file(), page
    assert (out / MARKER_NAME).is_file()
    # and the export is itself a directory 'envcap view' takes
    site = open_site(out)
    assert site.probe_dir == (out / "set").resolve() and site.has_atlas


def test_bad_input_is_one_line_and_leaves_nothing(sets, tmp_path):
    plain, _ = sets
    r = run_envcap("export", "web", tmp_path / "missing", "--out", tmp_path / "site")
    lines = error_lines(r.stderr)
    assert r.returncode == 2 and len(lines) == 1 and "probe-set directory not found" in lines[0], r.stderr
    # a foreign, non-empty --out is refused and untouched
    mine = tmp_path / "photos"
    mine.mkdir()
    (mine / "a.jpg").write_bytes(b"precious")
    r = run_envcap("export", "web", plain, "--out", mine)
    assert r.returncode == 2 and MARKER_NAME in r.stderr and tree_bytes(mine) == {"a.jpg": b"precious"}
    # a probe set that fails half-way (probes.ktx2 truncated: the atlas cannot be made) leaves nothing
    broken = tmp_path / "broken"
    shutil.copytree(plain, broken)
    data = (broken / "probes.ktx2").read_bytes()
    (broken / "probes.ktx2").write_bytes(data[: len(data) // 2])
    r = run_envcap("export", "web", broken, "--out", tmp_path / "out" / "site")
    lines = error_lines(r.stderr)
    assert r.returncode == 2 and len(lines) == 1 and "probes.ktx2" in lines[0], r.stderr
    assert not (tmp_path / "out").exists(), sorted(p.name for p in tmp_path.iterdir())
    # an unknown target: argparse's one line, exit 2
    r = run_envcap("export", "webgpu", plain, "--out", tmp_path / "x")
    assert r.returncode == 2 and "invalid choice: 'webgpu'" in r.stderr


def test_an_export_target_is_one_registration(sets, tmp_path):
    """docs/architecture.md "... an export target": registered here, found by the command."""
    plain, _ = sets

    def write(source, out_dir, report):
        shutil.copyfile(source / "manifest.json", out_dir / "manifest.json")
        return "copied {out}"

    register_target(ExportTarget("manifest_copy", "the manifest alone", "manifest-copy", write))
    try:
        out = tmp_path / "m"
        assert main(["export", "manifest_copy", str(plain), "--out", str(out)]) == 0
        assert (out / "manifest.json").read_bytes() == (plain / "manifest.json").read_bytes()
        assert "manifest-copy" in (out / MARKER_NAME).read_text()
        with pytest.raises(ValueError, match="already registered"):
            register_target(ExportTarget("manifest_copy", "", "", write))
    finally:
        unregister_target("manifest_copy")
