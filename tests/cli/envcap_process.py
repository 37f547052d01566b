"""Run the real ``envcap`` command in a child process, from any working directory, and compare
output directories file by file."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def envcap_env() -> dict[str, str]:
    """The environment of a child ``python -m envcap`` that imports this checkout from any cwd."""
    env = dict(os.environ, PYOPENGL_PLATFORM="egl")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])
    return env


def envcap_command(*args: object) -> list[str]:
    return [sys.executable, "-m", "envcap", *map(str, args)]


def run_envcap(*args: object, cwd: Path | None = None, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run(envcap_command(*args), capture_output=True, text=True, cwd=cwd, env=envcap_env(), check=False,
                          timeout=timeout)


def start_envcap(*args: object, cwd: Path | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen(envcap_command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=cwd, env=envcap_env())


def error_lines(stderr: str) -> list[str]:
    """The ``envcap: ...`` lines of a run's stderr (progress lines left out)."""
    return [ln for ln in stderr.splitlines() if ln.startswith("envcap:") or "Traceback" in ln]


def tree_bytes(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (hidden ones too): relative path -> content."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def without_timings(files: dict[str, bytes]) -> dict[str, object]:
    """``tree_bytes`` of a probe set with the manifest parsed and its run times dropped (the only
    part of a probe set that differs between two runs of the same command)."""
    out: dict[str, object] = dict(files)
    if "manifest.json" in files:
        manifest = json.loads(files["manifest.json"])
        manifest.pop("timings", None)
        out["manifest.json"] = manifest
    return out
