"""What envcap will never do to your files, through the real command line (issue 9, items 1, 2
and the output part of 8): each case below once lost data or left files behind.

Every refusal is one line ``envcap: error: ...``, exit 2, before any work, and leaves the
folder exactly as it was.
"""

import os
import re
import shutil
import signal
import time

import pytest
from envcap_process import error_lines, run_envcap, start_envcap, tree_bytes

from envcap.outputs import MARKER_NAME
from envcap.scene import scene_path

BAKE = ("--resolution", "8", "--spacing", "50", "--exr")


def _refused(r, *words):
    lines = error_lines(r.stderr)
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("envcap: error:"), r.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert "probes on" not in r.stderr, "refused only after the bake began"


@pytest.fixture(scope="module")
def probe_set(tmp_path_factory):
    """A small real probe set (with per-probe EXR files), baked once for this module."""
    out = tmp_path_factory.mktemp("baked") / "P"
    r = run_envcap("capture", "planes", "--out", out, *BAKE)
    assert r.returncode == 0, r.stderr
    return out


def _copy(src, dst):
    shutil.copytree(src, dst)
    return tree_bytes(dst)


# Item 1: "--out pointing at an existing non-empty directory that envcap did not create deletes
# it whole" (was: exit 0, the folder replaced).  Now: refused; replaced only with --force.
def test_a_foreign_folder_is_refused_and_replaced_only_with_force(tmp_path):
    mine = tmp_path / "photos"
    mine.mkdir()
    (mine / "holiday.jpg").write_bytes(b"precious")
    _refused(run_envcap("capture", "planes", "--out", mine, *BAKE), str(mine), MARKER_NAME, "--force")
    assert tree_bytes(mine) == {"holiday.jpg": b"precious"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photos"]
    r = run_envcap("capture", "planes", "--out", mine, *BAKE, "--force")
    assert r.returncode == 0, r.stderr
    assert (mine / MARKER_NAME).is_file() and (mine / "probes.ktx2").is_file() and not (mine / "holiday.jpg").exists()
    # --force moved the folder aside, whole, and said where (issue 19: it used to delete it)
    aside = [p for p in tmp_path.iterdir() if p.name.startswith("photos.envcap-replaced-")]
    assert len(aside) == 1 and re.fullmatch(r"photos\.envcap-replaced-\d{8}-\d{6}", aside[0].name)
    assert tree_bytes(aside[0]) == {"holiday.jpg": b"precious"}
    assert f"moved it to {aside[0]}" in r.stderr
    # envcap's own output is then replaced in place, without --force and without a copy aside
    r = run_envcap("capture", "planes", "--out", mine, *BAKE)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["photos", aside[0].name])


# Item 1: "--out = the folder that holds the scene file deletes the scene file" (was: exit 0,
# scene gone).  Now: refused, --force or not; also a folder holding a mesh the scene imports.
def test_the_scenes_folder_and_its_mesh_folder_are_never_outputs(tmp_path):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    shutil.copy(scene_path("planes"), scenes / "planes.toml")
    before = tree_bytes(scenes)
    for out in (scenes, tmp_path):
        _refused(run_envcap("capture", scenes / "planes.toml", "--out", out, *BAKE, "--force"), "contains the input")
    assert tree_bytes(scenes) == before
    meshes = tmp_path / "meshes"
    shutil.copytree(scene_path("imported").parent / "imported_block", meshes / "block")
    text = scene_path("imported").read_text().replace('file = "imported_block/"', 'file = "../meshes/block/"')
    assert "../meshes/block/" in text
    (scenes / "imported.toml").write_text(text)
    mesh_files = tree_bytes(meshes)
    _refused(run_envcap("capture", scenes / "imported.toml", "--out", meshes, *BAKE, "--force"),
             f"contains the input {meshes / 'block'}")
    assert tree_bytes(meshes) == mesh_files


# Item 1: "--out . empties the working directory and then exits 2" (was: cwd emptied).  Now:
# refused, --force or not, for the working directory and every folder above it.
@pytest.mark.parametrize("out", [".", "..", "../.."])
def test_the_working_directory_is_never_an_output(tmp_path, out):
    work = tmp_path / "a" / "work"
    work.mkdir(parents=True)
    (work / "notes.txt").write_text("keep")
    before = tree_bytes(tmp_path)
    _refused(run_envcap("capture", "planes", "--out", out, *BAKE, "--force", cwd=work), "working directory")
    assert tree_bytes(tmp_path) == before


# Item 1: "envcap evaluate S --probes P --out P destroys the probe set" (was: P replaced by the
# report).  Now: refused, P byte-identical.
def test_evaluate_never_writes_over_its_probe_set(tmp_path, probe_set):
    before = _copy(probe_set, tmp_path / "P")
    _refused(run_envcap("evaluate", "planes", "--probes", tmp_path / "P", "--out", tmp_path / "P", "--force"),
             "is the input")
    _refused(run_envcap("evaluate", "planes", "--probes", tmp_path / "P", "--out", tmp_path), "contains the input")
    assert tree_bytes(tmp_path / "P") == before


# Item 1: "envcap prefilter P/exr/probe_000.exr --out P destroys its own input" (was: P
# replaced).  Now: refused, P byte-identical.
def test_prefilter_never_writes_over_its_input(tmp_path, probe_set):
    before = _copy(probe_set, tmp_path / "P")
    src = tmp_path / "P" / "exr" / "probe_000.exr"
    for out in (tmp_path / "P", tmp_path / "P" / "exr"):
        _refused(run_envcap("prefilter", src, "--out", out, "--force"), "contains the input", str(src))
    assert tree_bytes(tmp_path / "P") == before
    r = run_envcap("prefilter", src, "--out", tmp_path / "chain")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "chain" / MARKER_NAME).is_file()


# Item 8: "An --out that is a file or read-only is reported only after the whole bake" (was:
# error after the bake).  Now: one line before any work.
def test_an_output_that_cannot_be_written_is_refused_before_any_work(tmp_path):
    (tmp_path / "file").write_text("x")
    _refused(run_envcap("capture", "planes", "--out", tmp_path / "file", *BAKE), "not a directory")
    _refused(run_envcap("capture", "planes", "--out", tmp_path / "file" / "sub", *BAKE), "is not a directory")
    _refused(run_envcap("scenes", "planes", "--preview", tmp_path / "file"), "not a directory")
    assert tree_bytes(tmp_path) == {"file": b"x"}


# "envcap never overwrites a file it did not write": scenes --preview DIR writes single PNG files
# beside the user's own (e.g. docs/images); it used to replace any DIR/scenes_NAME.png.
def test_a_preview_png_envcap_did_not_write_is_not_overwritten(tmp_path):
    from PIL import Image

    theirs = tmp_path / "scenes_planes.png"
    theirs.write_bytes(b"their picture")
    _refused(run_envcap("scenes", "planes", "--preview", tmp_path), "was not written by envcap", "--force")
    assert tree_bytes(tmp_path) == {"scenes_planes.png": b"their picture"}
    r = run_envcap("scenes", "planes", "--preview", tmp_path, "--force")
    assert r.returncode == 0, r.stderr
    with Image.open(theirs) as img:
        assert img.info.get("Software") == "envcap"
    kept = [p for p in tmp_path.iterdir() if p.name != theirs.name]   # theirs, moved aside by --force
    assert len(kept) == 1 and re.fullmatch(r"scenes_planes\.envcap-replaced-\d{8}-\d{6}\.png", kept[0].name)
    assert kept[0].read_bytes() == b"their picture"
    first = theirs.read_bytes()
    r = run_envcap("scenes", "planes", "--preview", tmp_path)  # its own file: replaced without --force
    assert r.returncode == 0, r.stderr
    assert theirs.read_bytes() == first


def _read_only_folder(tmp_path):
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        return ro
    if not os.access("/proc/sys", os.W_OK):  # root ignores modes: a read-only mount instead
        return "/proc/sys"
    pytest.skip("no read-only folder available")


def test_a_read_only_parent_is_refused_before_any_work(tmp_path):
    ro = _read_only_folder(tmp_path)
    _refused(run_envcap("capture", "planes", "--out", f"{ro}/envcap-out", *BAKE), "not writable")


def _wait_for(path, proc, timeout=120):
    t0 = time.monotonic()
    while not os.path.exists(path):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < timeout
        time.sleep(0.02)


# Item 2: "Two runs with the same --out at once: the loser fails with [Errno 39] or [Errno 2]
# and leaves its complete .NAME.tmp-XXXX/ behind" (was: a traceback-less errno line after a
# whole bake, and a leftover).  Now: the second fails at once with one line and leaves nothing;
# the first completes.
def test_a_second_run_on_the_same_output_fails_at_once_and_leaves_nothing(tmp_path):
    out = tmp_path / "out"
    # enough work (a few seconds) that the first run still holds the output when the second one,
    # a new Python process, gets to it: the faster bake of issue 11 finished 32^2 in ~1 s
    first = start_envcap("capture", "planes", "--out", out, "--resolution", "64", "--spacing", "5", "--quality", "default",
                         "--exr", "--previews")
    try:
        _wait_for(tmp_path / ".out.lock", first)
        second = run_envcap("capture", "planes", "--out", out, *BAKE)
        assert first.poll() is None, "the first run ended before the second one tried"
        _refused(second, "another envcap run", str(out))
        _, err = first.communicate(timeout=300)
    finally:
        first.kill()
    assert first.returncode == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert (out / MARKER_NAME).is_file()


# Item 2: "SIGTERM ... while files are written leaves a 46 MB temporary folder" (was: the temp
# folder stayed, exit -15).  Now SIGTERM is handled like Ctrl-C: one line, exit 143 (130),
# nothing left, the previous output byte-identical.
@pytest.mark.parametrize("sig, code, line", [(signal.SIGTERM, 143, "envcap: terminated"),
                                             (signal.SIGINT, 130, "envcap: interrupted")])
def test_sigterm_and_ctrl_c_clean_up_and_keep_the_old_output(tmp_path, sig, code, line):
    out = tmp_path / "out"
    r = run_envcap("capture", "planes", "--out", out, *BAKE)
    assert r.returncode == 0, r.stderr
    before = tree_bytes(out)
    run = start_envcap("capture", "planes", "--out", out, "--resolution", "64", "--spacing", "20")
    _wait_for(tmp_path / ".out.lock", run)
    time.sleep(0.3)
    run.send_signal(sig)
    _, err = run.communicate(timeout=120)
    assert run.returncode == code and error_lines(err) == [line], err
    assert tree_bytes(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
