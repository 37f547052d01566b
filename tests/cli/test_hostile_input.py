"""Hostile input at the command line (issue 20, items 9 to 11): every message is one line that
names the path or the option, says what is wrong in words (no ``[Errno N]``, no ``np.float64``,
no internal names), and no library warning is printed around it; bad scene files fail
``envcap scenes``; a margin wider than a street is refused; ``demo`` says the spacing it uses and
does not leave an old evaluation beside new probes; ``evaluate`` reports progress."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from envcap.cli import build_parser, error_text, main
from envcap.outputs import OutputRefused, atomic_output_file
from envcap.outputs.marker import MARKER_NAME, write_marker
from envcap.probeset.progress import BakeProgress

REPO = Path(__file__).resolve().parents[2]
WALKER = REPO / "city_scenes" / "avatars" / "walker.glb"
IMPORTED = REPO / "city_scenes" / "imported.toml"


def _envcap(*args: object, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYOPENGL_PLATFORM="egl")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    return subprocess.run([sys.executable, "-m", "envcap", *map(str, args)], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=300)


def _one_line(capsys, argv: list[str]) -> str:
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("envcap: error: "), err
    assert "[Errno" not in err and "np.float64" not in err and "Traceback" not in err, err
    return err


@pytest.fixture
def odd_inputs(tmp_path):
    folder = tmp_path / "folder.glb"
    folder.mkdir()
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    return {"a directory": folder, "a FIFO (named pipe)": fifo, "a character device": Path("/dev/zero")}


def test_an_input_that_is_no_regular_file_says_what_it_is(tmp_path, capsys, odd_inputs):
    """Before: "not found" for each (the file is there); a FIFO is never opened (no hang)."""
    for kind, path in odd_inputs.items():
        for argv, what in ((["prefilter", path, "--out", tmp_path / "p"], "input file"),
                           (["avatar", path, "--out", tmp_path / "a.glb"], "input avatar"),
                           (["capture", path, "--out", tmp_path / "c"], "scene file")):
            err = _one_line(capsys, argv)
            assert f"{what} {path} is {kind}, not a regular file" in err, err
        if kind != "a directory":
            err = _one_line(capsys, ["evaluate", "canyon", "--probes", path, "--out", tmp_path / "e"])
            assert f"probe-set directory {path} is {kind}, not a directory" in err, err
    broken = tmp_path / "broken.exr"
    broken.symlink_to(tmp_path / "gone.exr")
    assert "which does not exist" in _one_line(capsys, ["prefilter", broken, "--out", tmp_path / "p"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.exr", "folder.glb", "pipe.toml"]


def test_system_errors_become_sentences_naming_the_path(tmp_path, capsys):
    (tmp_path / ".out.lock").mkdir()            # a folder where the lock file goes
    err = _one_line(capsys, ["capture", "planes", "--out", tmp_path / "out", "--resolution", "4"])
    assert f"cannot create its lock file {tmp_path / '.out.lock'}: a directory of that name is in the way" in err
    (tmp_path / "file").write_text("x")
    err = _one_line(capsys, ["avatar", WALKER, "--out", tmp_path / "file" / "a.glb"])
    assert f"{tmp_path / 'file'} is a file, not a folder" in err     # before: [Errno 17] File exists
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    assert "a loop of symbolic links" in _one_line(capsys, ["capture", "planes", "--out", tmp_path / "loop"])
    assert error_text(FileNotFoundError(2, "No such file or directory", "/x/y")) == "/x/y: no such file or directory"
    assert error_text(OSError(28, "No space left on device")) == "no space left on device (the disk is full)"
    assert error_text(ValueError("two\nlines")) == "two lines"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".out.lock", "file", "loop"]


def test_an_output_through_a_link_to_nothing_is_refused_naming_the_link(tmp_path, capsys):
    """Before: ``--out LINK`` with LINK -> a missing path wrote the output at the link's target (a
    folder or file the command never named); now one line names the link, and nothing is created."""
    links = {}
    for name, target in (("set", "gone_set"), ("deep", "gone_dir"), ("a.glb", "gone.glb"), ("previews", "gone_png")):
        links[name] = tmp_path / name
        links[name].symlink_to(tmp_path / target)
    for argv, link in ((["capture", "planes", "--out", links["set"], "--resolution", "4"], "set"),
                       (["capture", "planes", "--out", links["deep"] / "sub", "--resolution", "4"], "deep"),
                       (["avatar", WALKER, "--out", links["a.glb"]], "a.glb"),
                       (["scenes", "planes", "--preview", links["previews"]], "previews")):
        err = _one_line(capsys, argv)
        assert err.startswith(f"envcap: error: output {links[link]} is a symbolic link to {os.readlink(links[link])}, "
                              "which does not exist"), err
        assert "does not write through a link it did not make" in err, err
    with pytest.raises(OutputRefused, match="is a symbolic link to"), atomic_output_file(links["a.glb"]) as tmp:
        tmp.write_bytes(b"never")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(links)          # no target, no temporary
    assert all(os.readlink(links[n]) == str(tmp_path / t) for n, t in
               (("set", "gone_set"), ("deep", "gone_dir"), ("a.glb", "gone.glb"), ("previews", "gone_png")))


@pytest.mark.parametrize("preview", ["NOTADIR/p.png", "/proc/p.png", "/proc"])
def test_scenes_preview_where_nothing_can_be_written_fails_before_the_build(tmp_path, capsys, monkeypatch, preview):
    """Before: ``envcap scenes NAME --preview /proc/p.png`` built (and printed) the scene and failed
    at the write; ``root`` passes every permission check, so the folder is tried for real first."""
    if preview.startswith("/proc") and not Path("/proc/self").is_dir():
        pytest.skip("no /proc file system here")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "NOTADIR").write_text("a file")
    assert main(["scenes", "canyon", "--preview", preview]) == 2
    got = capsys.readouterr()
    assert got.out == "", got.out                                   # nothing built, nothing printed
    assert got.err.startswith("envcap: error: cannot ") and got.err.count("\n") == 1, got.err
    assert ("NOTADIR is not a directory" if preview.startswith("NOTADIR")
            else "nothing can be created in /proc") in got.err, got.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["NOTADIR"]


def test_messages_name_the_option_and_print_plain_numbers(tmp_path, capsys):
    for argv, words in (
            (["capture", "planes", "--out", tmp_path / "o", "--spacing", "0"], "probe spacing (--spacing)"),
            (["capture", "planes", "--out", tmp_path / "o", "--height", "1e30"], "probe height (--height)"),
            (["evaluate", "planes", "--bake", "0", "--out", tmp_path / "o"], "(evaluate --bake)"),
            (["avatar", WALKER, "--out", tmp_path / "a.glb", "--exclude-weight", "2"], "(--exclude-weight)"),
            (["avatar", WALKER, "--out", tmp_path / "a.glb", "--animation", "3"], "animation 3 (--animation)"),
            (["avatar", WALKER, "--out", tmp_path / "a.glb", "--k", "9"], "k (--k)")):
        assert words in _one_line(capsys, argv), argv
    scene = tmp_path / "cropped.toml"   # a crop box away from the mesh: before, [np.float64(5000.0), ...]
    scene.write_text(IMPORTED.read_text().replace('"imported_block/"', f'"{REPO}/city_scenes/imported_block/"')
                     .replace("scale = 1.0", "scale = 1.0\ncrop = { min = [5000.0, -10.0, 5000.0], max = [5100.0, 100.0, 5100.0] }"))
    err = _one_line(capsys, ["scenes", "--details", scene])
    assert "the crop box [5000.0, -10.0, 5000.0] .. [5100.0, 100.0, 5100.0] meets none" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cropped.toml"]


def test_library_warnings_do_not_surround_the_error_line(tmp_path):
    """A PLY coordinate past float32 made numpy warn through trimesh (2 lines) before the error."""
    (tmp_path / "big.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                      "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                      "end_header\n0 0 0\n1 0 0\n0 1e39 0\n3 0 1 2\n")
    (tmp_path / "big.toml").write_text(IMPORTED.read_text().replace('"imported_block/"', '"big.ply"'))
    r = _envcap("scenes", "--details", tmp_path / "big.toml")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "big.ply has NaN or Inf vertex positions" in r.stderr and "RuntimeWarning" not in r.stderr


def test_scenes_checks_each_named_file_and_exits_2_on_a_bad_one(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nbogus')
    assert "invalid TOML" in _one_line(capsys, ["scenes", bad])          # before: printed "bad.toml", exit 0
    narrow = tmp_path / "narrow.toml"
    narrow.write_text((REPO / "city_scenes" / "canyon.toml").read_text().replace("width = 16.0", "width = 1e-300"))
    assert "streets[0].width: must be >= 1, got 1e-300" in _one_line(capsys, ["scenes", narrow])
    assert main(["scenes", "canyon", str(IMPORTED)]) == 0
    assert "Imported Z-up PLY boxes" in capsys.readouterr().out


def test_a_margin_wider_than_a_street_is_refused_naming_its_width(tmp_path, capsys):
    err = _one_line(capsys, ["evaluate", "canyon", "--bake", "40", "--margin", "100", "--out", tmp_path / "e"])
    assert "--margin 100 m leaves no room across street 'main'" in err and "16 m between its facades" in err
    assert list(tmp_path.iterdir()) == []


def test_demo_help_says_the_spacing_the_demo_uses(capsys):
    parser = build_parser()
    args = parser.parse_args(["demo"])
    with pytest.raises(SystemExit):
        parser.parse_args(["demo", "--help"])
    assert f"(default {args.spacing:g})" in " ".join(capsys.readouterr().out.split()) and args.spacing == 10.0


def test_progress_lines_say_what_a_running_stage_has_done():
    out = io.StringIO()
    rep = BakeProgress("lines", out, unit="position", interval=0.0)
    with rep.stage("positions", 3):
        rep.advance()
        rep.advance()
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("progress: positions: 1/3 positions, ") and lines[0].endswith("positions/s")
    assert lines[1].startswith("progress: positions: 2/3 positions, ")
    assert lines[2].startswith("progress: positions: 2 positions in ")
    quiet = io.StringIO()
    rep = BakeProgress("off", quiet, interval=0.0)
    with rep.stage("positions", 3):
        rep.advance()
    assert quiet.getvalue() == ""


@pytest.mark.slow
def test_evaluate_reports_progress_and_quiet_silences_it(tmp_path):
    args = ["evaluate", "canyon", "--bake", "30", "--probe-resolution", "8", "--resolution", "8", "--positions", "2",
            "--lobes", "inf,16", "--methods", "planes", "--no-images"]
    r = _envcap(*args, "--out", tmp_path / "a")
    assert r.returncode == 0, r.stderr
    for stage in ("positions: 2 positions in", "floor: ", "strips: "):
        assert f"progress: {stage}" in r.stderr, r.stderr
    assert "positions/s" in r.stderr
    q = _envcap(*args, "--out", tmp_path / "b", "--quiet")
    assert q.returncode == 0 and "progress:" not in q.stderr, q.stderr


def test_demo_no_eval_removes_only_an_evaluation_envcap_wrote(tmp_path, capsys):
    args = ["demo", "--out", str(tmp_path), "--resolution", "8", "--spacing", "150", "--no-exr", "--no-previews",
            "--no-eval", "--quiet"]
    old = tmp_path / "evaluation"
    old.mkdir()
    (old / "report.md").write_text("errors of the earlier probes")
    write_marker(old, "evaluation-report")
    assert main(args) == 0
    assert not old.exists() and "removed" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["probes"]
    theirs = tmp_path / "evaluation"
    theirs.mkdir()
    (theirs / "notes.txt").write_text("mine")
    assert main(args) == 0
    assert "is stale" in capsys.readouterr().err and (theirs / "notes.txt").read_text() == "mine"
    assert not (theirs / MARKER_NAME).exists()
