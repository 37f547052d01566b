"""A full disk (issue 20, item 8): a 3 MiB tmpfs mounted in a private mount namespace
(``unshare --mount``; skipped where that is not allowed), filled with a file.  Each command fails
with one line that names its output and says the disk is full, and leaves nothing behind: no
temporary folder or file, no ``.NAME.lock`` (before: a 0-byte lock file per run, and
``[Errno 28] No space left on device`` naming no path)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
WALKER = REPO / "city_scenes" / "avatars" / "walker.glb"


def _in_full_tmpfs(tmp_path: Path, free_kib: int, commands: list[str]) -> list[tuple[int, str, list[str]]]:
    """Run each envcap command line (``{mnt}`` replaced) on a 3 MiB tmpfs with ``free_kib`` KiB
    left free; return per command ``(exit status, stderr, the names in the tmpfs after it)``."""
    unshare = shutil.which("unshare")
    if unshare is None:
        pytest.skip("no unshare(1)")
    probe = subprocess.run([unshare, "--mount", "--propagation", "private", "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip(f"no private mount namespace here: {probe.stderr.decode().strip()}")
    mnt = tmp_path / "mnt"
    mnt.mkdir(parents=True)
    env = dict(os.environ, PYOPENGL_PLATFORM="egl")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    lines = [f"mount -t tmpfs -o size=3m envcap-test {mnt} || exit 9",
             f"dd if=/dev/zero of={mnt}/fill bs=1k count={3072 - free_kib} 2>/dev/null"]
    for i, cmd in enumerate(commands):
        lines += [f"{sys.executable} -m envcap {cmd.format(mnt=mnt)} 2> {tmp_path}/err{i}; echo rc{i}=$?",
                  f"echo ls{i}=$(ls -A {mnt})"]
    r = subprocess.run([unshare, "--mount", "--propagation", "private", "sh", "-c", "\n".join(lines)],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    if r.returncode == 9:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    out = dict(line.split("=", 1) for line in r.stdout.splitlines() if "=" in line)
    assert f"rc{len(commands) - 1}" in out, (r.stdout, r.stderr)
    return [(int(out[f"rc{i}"]), (tmp_path / f"err{i}").read_text(), out[f"ls{i}"].split()) for i in range(len(commands))]


@pytest.mark.slow
def test_a_full_disk_leaves_nothing_and_names_the_output(tmp_path):
    nearly = _in_full_tmpfs(tmp_path / "a", 200, ["capture planes --out {mnt}/p --resolution 16 --exr --previews --quiet"])
    full = _in_full_tmpfs(tmp_path / "b", 0, ["capture planes --out {mnt}/p --resolution 8 --quiet",
                                              f"avatar {WALKER} --out {{mnt}}/a.glb --quiet"])
    for (rc, err, left), out in zip(nearly + full, ["p", "p", "a.glb"]):
        assert rc == 2, err
        assert err.count("\n") == 1 and err.startswith(f"envcap: error: cannot write {tmp_path}"), err
        assert f"/mnt/{out}" in err and "the disk is full" in err, err
        assert left == ["fill"], (err, left)          # no .p.lock, no .p.tmp-*, no .a.glb.tmp-*.glb
