"""A probe set is untrusted input (sets are downloaded and shared): its manifest, a city's
``city.json``, its symbolic links and its report.  ``envcap view`` and ``envcap export web`` must
never read a file outside the set, whatever the set names: an absolute path, ``../`` in a name,
a link (a file or a folder) that leads outside, a shard folder that is a link, a file swapped for
a link while the server runs.  The target is a secret file in the test's temporary folder beside
the set (never a real system file); each case asserts that its bytes are neither served (raw
requests, the path sent as is) nor copied into an export, and that the set is refused in one line
naming the entry when its manifest names a file outside it."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from raw_http import get

from envcap.probeset.manifest import ManifestError, read_manifest
from envcap.viewer import serve
from envcap.viewer.site_dir import open_site

SECRET = b"envcap-test-secret-7b1e55a0 " * 8
REPO = Path(__file__).resolve().parents[2]


def edit_manifest(set_dir: Path, **files) -> None:
    m = json.loads((set_dir / "manifest.json").read_text())
    m["files"].update(files)
    (set_dir / "manifest.json").write_text(json.dumps(m, indent=2) + "\n")


def absolute(set_dir: Path, secret: Path) -> list[str]:
    edit_manifest(set_dir, extra=[str(secret)])
    return ["/set/" + str(secret), "/set/" + str(secret).lstrip("/")]


def traversal(set_dir: Path, secret: Path) -> list[str]:
    rel = os.path.relpath(secret, set_dir)                    # ../secret.bin
    edit_manifest(set_dir, extra=[rel, "sub/../../" + secret.name], notes="./../" + secret.name)
    return ["/set/" + rel, "/set/sub/../../" + secret.name, "/set/./../" + secret.name, "/set/%2e%2e/" + secret.name]


def file_link(set_dir: Path, secret: Path) -> list[str]:
    (set_dir / "notes.bin").symlink_to(secret)
    edit_manifest(set_dir, notes="notes.bin")
    return ["/set/notes.bin"]


def folder_link(set_dir: Path, secret: Path) -> list[str]:
    (set_dir / "up").symlink_to(secret.parent, target_is_directory=True)
    edit_manifest(set_dir, notes="up/" + secret.name)
    return ["/set/up/" + secret.name]


def atlas_link(set_dir: Path, secret: Path) -> list[str]:
    """The face atlas the viewer needs is a link to a file outside (a valid atlas: the set opens today)."""
    secret.write_bytes((set_dir / "probes_atlas.ktx2").read_bytes())
    (set_dir / "probes_atlas.ktx2").unlink()
    (set_dir / "probes_atlas.ktx2").symlink_to(secret)
    return ["/set/probes_atlas.ktx2"]


def sky_traversal(set_dir: Path, secret: Path) -> list[str]:
    """``files.sky`` names a valid sky map outside the set."""
    secret.write_bytes((set_dir / "sky.ktx2").read_bytes())
    edit_manifest(set_dir, sky=os.path.relpath(secret, set_dir))
    (set_dir / "sky.ktx2").unlink()
    return ["/set/" + os.path.relpath(secret, set_dir)]


SCENARIOS = {f.__name__: f for f in (absolute, traversal, file_link, folder_link, atlas_link, sky_traversal)}


@pytest.fixture
def hostile(web_probe_dir, tmp_path, request):
    """``(set_dir, secret, targets)``: a copy of the probe set made hostile by the scenario
    ``request.param``, the secret file beside it, the URL paths that would reach the secret."""
    set_dir = tmp_path / "downloads" / "set"
    shutil.copytree(web_probe_dir, set_dir)
    secret = tmp_path / "downloads" / "secret.bin"
    secret.write_bytes(SECRET)
    targets = SCENARIOS[request.param](set_dir, secret)
    return set_dir, secret, targets


def assert_never_served(server, secret: Path, targets: list[str]) -> None:
    port = server.server_address[1]
    for t in [*targets, *server.routes]:
        r = get(port, t)
        assert secret.read_bytes() not in r.raw, f"{t} served the secret"


@pytest.mark.parametrize("hostile", list(SCENARIOS), indirect=True)
def test_the_viewer_refuses_a_set_naming_a_file_outside_it(hostile):
    set_dir, secret, targets = hostile
    try:
        site = open_site(set_dir)
    except ValueError as e:
        text = str(e)
        assert "\n" not in text and "outside" in text, text
        return
    server, thread = serve(site)    # only reached on the code before the fix: then it must not leak either
    try:
        assert_never_served(server, secret, targets)
    finally:
        server.shutdown()
        server.server_close()
    pytest.fail("a set naming a file outside it was opened")


@pytest.mark.parametrize("hostile", list(SCENARIOS), indirect=True)
def test_export_web_never_copies_a_file_outside_the_set(hostile, tmp_path):
    from envcap.export.web import write_web_site

    set_dir, secret, _ = hostile
    out = tmp_path / "site"
    out.mkdir()
    with pytest.raises(ValueError, match="outside"):
        write_web_site(set_dir, out, None)
    written = [p for p in out.rglob("*") if p.is_file()]
    assert not [p for p in written if secret.read_bytes() in p.read_bytes()]


def test_export_never_makes_an_atlas_from_probes_outside_the_set(web_probe_dir, tmp_path):
    """A set without the face atlas (the export makes it from ``probes.ktx2``) whose ``probes.ktx2``
    is a link to another set's: neither copied nor read."""
    from envcap.export.web import write_web_site

    set_dir = tmp_path / "downloads" / "set"
    shutil.copytree(web_probe_dir, set_dir)
    secret = tmp_path / "downloads" / "other.ktx2"
    secret.write_bytes((set_dir / "probes.ktx2").read_bytes())
    (set_dir / "probes.ktx2").unlink()
    (set_dir / "probes.ktx2").symlink_to(secret)
    (set_dir / "probes_atlas.ktx2").unlink()
    m = json.loads((set_dir / "manifest.json").read_text())
    m["files"].pop("probes_atlas", None)
    (set_dir / "manifest.json").write_text(json.dumps(m))
    out = tmp_path / "site"
    out.mkdir()
    with pytest.raises(ValueError, match="outside"):
        write_web_site(set_dir, out, None)
    assert not (out / "set" / "probes.ktx2").exists() and not (out / "set" / "probes_atlas.ktx2").exists()


def test_a_report_plot_that_links_outside_is_neither_listed_nor_served(web_probe_dir, tmp_path):
    set_dir = tmp_path / "downloads" / "set"
    shutil.copytree(web_probe_dir, set_dir)
    secret = tmp_path / "downloads" / "secret.png"
    secret.write_bytes(SECRET)
    rep = set_dir / "evaluation"
    rep.mkdir()
    (rep / "report.json").write_text('{"positions": []}\n')
    (rep / "plot.png").symlink_to(secret)
    site = open_site(set_dir)
    assert site.report_dir == rep.resolve() and site.config()["plots"] == []
    server, _ = serve(site)
    try:
        assert_never_served(server, secret, ["/report/plot.png"])
    finally:
        server.shutdown()
        server.server_close()


def test_a_file_swapped_for_a_link_while_serving_is_not_served(web_probe_dir, tmp_path):
    set_dir = tmp_path / "downloads" / "set"
    shutil.copytree(web_probe_dir, set_dir)
    secret = tmp_path / "downloads" / "secret.bin"
    secret.write_bytes(SECRET)
    server, _ = serve(open_site(set_dir))
    try:
        port = server.server_address[1]
        assert get(port, "/set/sky.ktx2").status == 200
        (set_dir / "sky.ktx2").unlink()
        (set_dir / "sky.ktx2").symlink_to(secret)
        r = get(port, "/set/sky.ktx2")
        assert r.status == 404 and SECRET not in r.raw
    finally:
        server.shutdown()
        server.server_close()


@pytest.mark.parametrize("key, name", [("extra", ["/etc/x"]), ("notes", "../x"), ("sky", "a/../../x"), ("probes", ""),
                                       ("exr", ["exr/p0.exr", "../p1.exr"]), ("contact_sheet", "C:\\x.png"),
                                       ("notes", "..\\..\\x"), ("notes", "x\x00.png")])
def test_the_manifest_reader_refuses_a_file_name_outside_the_set(web_probe_dir, tmp_path, key, name):
    m = json.loads((web_probe_dir / "manifest.json").read_text())
    m["files"][key] = name
    (tmp_path / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(ManifestError, match=rf"files\.{key}.*inside the probe set"):
        read_manifest(tmp_path / "manifest.json")


def test_the_cli_refuses_a_hostile_set_in_one_line_and_writes_nothing(web_probe_dir, tmp_path):
    set_dir = tmp_path / "set"
    shutil.copytree(web_probe_dir, set_dir)
    edit_manifest(set_dir, extra=[str(tmp_path / "secret.bin")])
    (tmp_path / "secret.bin").write_bytes(SECRET)
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    for args in (["view", "set"], ["export", "web", "set", "--out", "site"]):
        r = subprocess.run([sys.executable, "-m", "envcap", *args], cwd=tmp_path, capture_output=True, text=True,
                           timeout=60, env=env)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.returncode == 2 and len(lines) == 1, r.stderr
        assert lines[0].startswith("envcap: error: ") and "files.extra" in lines[0] and "outside" in lines[0], lines
        assert "envcap viewer: http" not in r.stdout
    assert not (tmp_path / "site").exists()


# --------------------------------------------------------------------------------------------
# A city: city.json and its shard folders are untrusted too


@pytest.fixture(scope="module")
def city_dir(gl_ctx, tmp_path_factory):
    """The bundled crossing as a city: two streets, one shard each, 8^2 faces, with face atlases (~1 s)."""
    from envcap.city.bake import bake_city
    from envcap.city.plan import BakeSettings

    out = tmp_path_factory.mktemp("hostile_city") / "crossing"
    bake_city("crossing", out, BakeSettings(resolution=8, spacing=100.0, writers=("ktx2", "webgl2")), budget_mb=0,
              ctx=gl_ctx)
    return out


def test_a_city_street_map_outside_the_city_is_refused(city_dir, tmp_path):
    city = tmp_path / "downloads" / "city"
    shutil.copytree(city_dir, city)
    secret = tmp_path / "downloads" / "secret.bin"
    secret.write_bytes(SECRET)
    ix = json.loads((city / "city.json").read_text())
    assert ix["street_map"]["file"]
    ix["street_map"]["file"] = "../secret.bin"
    (city / "city.json").write_text(json.dumps(ix))
    with pytest.raises(ValueError, match=r"street_map.*inside the city"):
        open_site(city)


def test_a_city_shard_folder_that_links_outside_is_refused(city_dir, tmp_path):
    city = tmp_path / "downloads" / "city"
    shutil.copytree(city_dir, city)
    shard = json.loads((city / "city.json").read_text())["shards"][0]["path"]
    elsewhere = tmp_path / "elsewhere"
    shutil.move(city / shard, elsewhere)
    (elsewhere / "notes.bin").write_bytes(SECRET)
    edit_manifest(elsewhere, notes="notes.bin")
    (city / shard).symlink_to(elsewhere, target_is_directory=True)
    try:
        site = open_site(city)
    except ValueError as e:
        assert "outside" in str(e) and "\n" not in str(e)
        return
    server, _ = serve(site)
    try:
        assert_never_served(server, elsewhere / "notes.bin", [f"/set/{shard}/notes.bin"])
    finally:
        server.shutdown()
        server.server_close()
    pytest.fail("a city whose shard folder links outside it was opened")
