"""Where ``babylon.html`` gets Babylon.js (envcap/viewer/babylon_build.py): an npm install found by
``$ENVCAP_BABYLON`` or in envcap's npm cache; ``envcap export web`` copies it with its license, or
says in one line how to install it (the page is written either way); ``.ci/run`` installs the
version the page is tested with by the module's own command."""

import json
from pathlib import Path

import pytest

from envcap.cli import main
from envcap.probeset.store import write_probe_set
from envcap.viewer.babylon_build import INSTALL_COMMAND, VERSION, find_babylon
from envcap.viewer.site import page_routes

REPO = Path(__file__).resolve().parents[2]


def fake_package(folder: Path, version: str = "9.1.2") -> Path:
    """A folder laid out as the npm package (the files the site carries; not a working build)."""
    folder.mkdir(parents=True)
    (folder / "babylon.js").write_text("/* babylon */ var BABYLON = {};\n")
    (folder / "license.md").write_text("Apache License 2.0\n")
    (folder / "NOTICE.md").write_text("notice\n")
    (folder / "package.json").write_text(json.dumps({"name": "babylonjs", "version": version}))
    return folder


def test_found_by_env_folder_or_file_else_in_the_cache(tmp_path, monkeypatch):
    pkg = fake_package(tmp_path / "pkg")
    monkeypatch.setenv("ENVCAP_BABYLON", str(pkg))
    b = find_babylon()
    assert b is not None and b.version == "9.1.2"
    assert b.files == {"babylon.js": pkg / "babylon.js", "babylon.LICENSE.md": pkg / "license.md",
                       "babylon.NOTICE.md": pkg / "NOTICE.md"}
    monkeypatch.setenv("ENVCAP_BABYLON", str(pkg / "babylon.js"))   # the file itself
    assert find_babylon() == b
    monkeypatch.setenv("ENVCAP_BABYLON", str(tmp_path))              # a folder without the build
    assert find_babylon() is None
    monkeypatch.delenv("ENVCAP_BABYLON")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert find_babylon() is None
    fake_package(tmp_path / "cache" / "envcap" / "npm" / "node_modules" / "babylonjs", "9.35.0")
    b = find_babylon()
    assert b is not None and b.version == "9.35.0"
    assert page_routes()["/babylon/babylon.js"] == b.files["babylon.js"]


@pytest.fixture(scope="module")
def canyon_atlas_set(canyon_probe_set, tmp_path_factory):
    """The session canyon written with its face atlas."""
    return write_probe_set(tmp_path_factory.mktemp("babylon") / "set", canyon_probe_set, exr=False, previews=False,
                           writers=["ktx2", "webgl2"])


def test_export_copies_the_build_with_its_license_or_says_how_to_get_it(canyon_atlas_set, tmp_path, monkeypatch, capsys):
    pkg = fake_package(tmp_path / "pkg")
    monkeypatch.setenv("ENVCAP_BABYLON", str(pkg))
    assert main(["export", "web", str(canyon_atlas_set), "--out", str(tmp_path / "with")]) == 0
    assert "babylon.html (Babylon.js)" in capsys.readouterr().out
    site = tmp_path / "with"
    for name, src in (("babylon.js", "babylon.js"), ("babylon.LICENSE.md", "license.md"), ("babylon.NOTICE.md", "NOTICE.md")):
        assert (site / "babylon" / name).read_bytes() == (pkg / src).read_bytes()
    assert (site / "babylon.html").read_bytes() == (REPO / "envcap/viewer/web/babylon.html").read_bytes()
    assert "Babylon.js 9.1.2" in (site / "README.md").read_text()
    for page in ("web/babylon_probes.js", "web/babylon_example.js", "three.html"):
        assert (site / page).is_file(), page

    monkeypatch.setenv("ENVCAP_BABYLON", str(tmp_path / "nowhere"))
    assert main(["export", "web", str(canyon_atlas_set), "--out", str(tmp_path / "without")]) == 0
    note = [line for line in capsys.readouterr().out.splitlines() if line.startswith("note:")]
    assert len(note) == 1 and INSTALL_COMMAND in note[0], note
    assert (tmp_path / "without" / "babylon.html").is_file() and not (tmp_path / "without" / "babylon").exists()
    assert "npm install" in (tmp_path / "without" / "README.md").read_text()


def test_ci_installs_the_version_the_page_is_tested_with():
    ci = (REPO / ".ci" / "run").read_text()
    assert INSTALL_COMMAND in ci and f'"version": "{VERSION}"' in ci
