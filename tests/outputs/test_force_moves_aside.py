"""``--force`` never deletes: a non-empty output envcap did not write is renamed beside itself
(``NAME.envcap-replaced-YYYYmmdd-HHMMSS``), and some paths are never outputs, ``--force`` or not:
the file system root, an existing top-level directory, a mount point, the home directory and
the folders above it.

Every case runs inside a temporary directory: the system paths are played by stand-ins (a fake
root and home passed to :func:`protected_reason`, ``HOME`` pointed at a temporary folder, a
tmpfs mounted in a private mount namespace), never by the real ones."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from envcap.outputs import OutputRefused, atomic_output_dir, atomic_output_file, claim_output_dir
from envcap.outputs.guard import protected_reason
from envcap.outputs.swap import move_aside, replaced_name

REPO = Path(__file__).resolve().parents[2]
ASIDE = re.compile(r"photos\.envcap-replaced-\d{8}-\d{6}(-\d+)?")


def _photos(tmp_path):
    mine = tmp_path / "photos"
    (mine / "2024").mkdir(parents=True)
    (mine / "2024" / "holiday.jpg").write_bytes(b"precious")
    return mine


def _tree(root):
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_force_moves_a_foreign_directory_aside_whole(tmp_path, capsys):
    mine = _photos(tmp_path)
    with claim_output_dir(mine, kind="probe-set", force=True) as claim, atomic_output_dir(claim) as d:
        (d / "a.txt").write_text("new")
    aside = [p for p in tmp_path.iterdir() if p != mine]
    assert len(aside) == 1 and ASIDE.fullmatch(aside[0].name)
    assert _tree(aside[0]) == {"2024/holiday.jpg": b"precious"}
    assert claim.moved_aside == aside[0]
    assert (mine / "a.txt").read_text() == "new"
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"moved it to {aside[0]}" in err and "nothing was deleted" in err


def test_a_failed_run_leaves_the_foreign_directory_in_place(tmp_path):
    mine = _photos(tmp_path)
    with pytest.raises(RuntimeError, match="boom"):
        with atomic_output_dir(mine, force=True) as d:
            (d / "half.txt").write_text("half")
            raise RuntimeError("boom")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photos"]
    assert _tree(mine) == {"2024/holiday.jpg": b"precious"}


def test_two_replacements_in_the_same_second_get_two_names(tmp_path):
    first = tmp_path / "photos"
    first.mkdir()
    (first / "f").write_text("1")
    a = move_aside(first)
    first.mkdir()
    (first / "f").write_text("2")
    b = move_aside(first)
    assert a != b and (a / "f").read_text() == "1" and (b / "f").read_text() == "2"
    assert replaced_name(tmp_path / "w.glb", 0.0).name.endswith(".glb")      # a file keeps its extension


def test_a_foreign_file_is_moved_aside_not_overwritten(tmp_path, capsys):
    theirs = tmp_path / "walker.glb"
    theirs.write_bytes(b"their avatar")
    with atomic_output_file(theirs, keep_existing=True) as tmp:
        tmp.write_bytes(b"envcap's")
    kept = [p for p in tmp_path.iterdir() if p != theirs]
    assert len(kept) == 1 and re.fullmatch(r"walker\.envcap-replaced-\d{8}-\d{6}\.glb", kept[0].name)
    assert kept[0].read_bytes() == b"their avatar" and theirs.read_bytes() == b"envcap's"
    assert "moved it to" in capsys.readouterr().err


def test_avatar_force_moves_the_foreign_file_aside(tmp_path, capsys):
    from envcap.cli import main
    from envcap.core.resources import city_scenes_dir

    theirs = tmp_path / "mine.glb"
    theirs.write_bytes(b"not envcap's")
    assert main(["avatar", str(city_scenes_dir() / "avatars" / "walker.glb"), "--out", str(theirs), "--force"]) == 0
    kept = [p for p in tmp_path.iterdir() if p != theirs]
    assert len(kept) == 1 and kept[0].read_bytes() == b"not envcap's"
    assert "moved it to" in capsys.readouterr().err


@pytest.mark.parametrize("rel, reason", [
    ("", "file system root"),
    ("etc", "top-level system directory"),
    ("usr", "top-level system directory"),
    ("home/user", "is the home directory"),
    ("home", "contains the home directory"),
])
def test_protected_paths_with_stand_ins(tmp_path, rel, reason):
    root = tmp_path / "root"
    for d in ("etc", "usr/lib", "home/user/projects"):
        (root / d).mkdir(parents=True)
    final = root / rel if rel else root
    why = protected_reason(final, root=root, home=root / "home" / "user")
    assert why is not None and reason in why
    # not protected: below home, deeper system folders are the user's choice, a new top-level name
    for ok in ("home/user/projects", "home/user/new", "usr/lib", "new_top"):
        assert protected_reason(root / ok, root=root, home=root / "home" / "user") is None, ok


def _envcap(args, env_extra=None, cwd=None):
    env = dict(os.environ, PYOPENGL_PLATFORM="egl", **(env_extra or {}))
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    return subprocess.run([sys.executable, "-m", "envcap", *map(str, args)], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=300)


def test_the_home_directory_is_never_an_output_even_with_force(tmp_path):
    home = tmp_path / "fakehome"
    (home / "docs").mkdir(parents=True)
    (home / "docs" / "thesis.tex").write_text("years of work")
    work = tmp_path / "elsewhere"
    work.mkdir()
    for out, words in ((home, "is the home directory"), (tmp_path, "contains the home directory")):
        r = _envcap(["capture", "planes", "--out", out, "--resolution", "8", "--force"], {"HOME": str(home)}, cwd=work)
        lines = [ln for ln in r.stderr.splitlines() if ln.startswith("envcap:")]
        assert r.returncode == 2 and len(lines) == 1 and words in lines[0] and "--force does not change" in lines[0]
    assert _tree(home) == {"docs/thesis.tex": b"years of work"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["elsewhere", "fakehome"]


def test_a_mount_point_is_never_an_output_even_with_force(tmp_path):
    """In a private mount namespace (``unshare --mount``): a tmpfs mounted on a temporary folder."""
    unshare = shutil.which("unshare")
    if unshare is None:
        pytest.skip("no unshare(1)")
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    probe = subprocess.run([unshare, "--mount", "--propagation", "private", "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip(f"no private mount namespace here: {probe.stderr.decode().strip()}")
    env = dict(os.environ, PYOPENGL_PLATFORM="egl")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    script = (f"mount -t tmpfs envcap-test {mnt} && echo kept > {mnt}/data.txt && "
              f"{sys.executable} -m envcap capture planes --out {mnt} --resolution 8 --force; "
              f"echo rc=$?; cat {mnt}/data.txt; ls -A {mnt}")
    r = subprocess.run([unshare, "--mount", "--propagation", "private", "sh", "-c", script], capture_output=True,
                       text=True, env=env, cwd=tmp_path, timeout=300)
    assert "rc=2" in r.stdout, (r.stdout, r.stderr)
    assert "is a mount point" in r.stderr and "--force does not change" in r.stderr
    assert r.stdout.split("rc=2")[1].split() == ["kept", "data.txt"]      # the mounted files, untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mnt"]


def test_city_bake_force_moves_a_foreign_directory_aside(tmp_path):
    mine = _photos(tmp_path)
    r = _envcap(["capture", "crossing", "--out", mine, "--resolution", "8", "--spacing", "100", "--workers", "0",
                 "--force"])
    assert r.returncode == 0, r.stderr
    aside = [p for p in tmp_path.iterdir() if p != mine]
    assert len(aside) == 1 and ASIDE.fullmatch(aside[0].name) and f"moved it to {aside[0]}" in r.stderr
    assert _tree(aside[0]) == {"2024/holiday.jpg": b"precious"}
    assert (mine / "city.json").is_file() and not (mine / "2024").exists()


def test_refused_before_any_work_and_nothing_left(tmp_path):
    root = tmp_path / "root"
    (root / "etc").mkdir(parents=True)
    with pytest.raises(OutputRefused, match="top-level"):
        from envcap.outputs.guard import check_protected

        check_protected(root / "etc", root=root, home=tmp_path / "nohome")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["root"]
