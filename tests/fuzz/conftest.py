"""Fixtures of the fuzz suite: a sandbox base, one small probe set baked per session and the
files cut from it; a summary of the fuzz figures at the end of the run (see fuzz_harness)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from fuzz_harness import REPO, figures
from hypothesis.configuration import set_hypothesis_home_dir

# Hypothesis keeps caches and writes failure patches in ./.hypothesis; the fuzz suite uses no
# example database (runs are derandomized), so its files go to the ignored .pytest_cache instead.
set_hypothesis_home_dir(str(REPO / ".pytest_cache" / "hypothesis"))

BAKE_ARGS = ["planes", "--resolution", "8", "--spacing", "50", "--exr"]
"""The session's probe set: the bundled ``planes`` street, 4 probes of 8^2 texels per face, 4 levels."""


@pytest.fixture(scope="session")
def fuzz_base(tmp_path_factory) -> Path:
    """Where the sandboxes of single cases are made (each removed after its case)."""
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(scope="session")
def baked(tmp_path_factory) -> Path:
    """A valid probe set (``manifest.json``, ``probes.ktx2``, ``sky.ktx2``, ``exr/probe_00N.exr``)."""
    from envcap.cli import main

    out = tmp_path_factory.mktemp("fuzz-baked") / "set"
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        status = main(["capture", *BAKE_ARGS, "--out", str(out)])
    assert status == 0 and (out / "manifest.json").is_file()
    return out


@pytest.fixture(scope="session")
def latlong_exr(tmp_path_factory) -> Path:
    """A valid 16 x 8 lat-long OpenEXR (RGB float32, a smooth sky with a bright spot)."""
    path = tmp_path_factory.mktemp("fuzz-latlong") / "sky.exr"
    y, x = np.mgrid[0:8, 0:16].astype(np.float32)
    rgb = np.stack([1 + x / 16, 1 + y / 8, np.full_like(x, 2.0)], -1).astype(np.float32)
    rgb[2, 5] = 5000.0
    channels = {c: np.ascontiguousarray(rgb[..., i]) for i, c in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))
    return path


@pytest.fixture
def fresh_copy(tmp_path):
    """``fresh_copy(src)``: a copy of a file or directory in this test's tmp_path."""
    def copy(src: Path) -> Path:
        dst = tmp_path / src.name
        if src.is_dir():
            shutil.copytree(src, dst)
        else:
            shutil.copyfile(src, dst)
        return dst

    return copy


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    figs = figures()
    if not figs:
        return
    tr = terminalreporter
    tr.section("envcap fuzz figures")
    cols = ["cases", "ok", "user_error", "traceback", "runaway", "leftover", "lost", "message", "nonfinite"]
    tr.write_line(f"{'target':<22}" + "".join(f"{c:>11}" for c in cols) + f"{'seconds':>9}  known")
    for target, c in figs.items():
        known = ", ".join(f"{k[6:]}={v}" for k, v in c.items() if k.startswith("known:"))
        tr.write_line(f"{target:<22}" + "".join(f"{c.get(k, 0):>11}" for k in cols) + f"{c['seconds']:>9.1f}  {known}")
    path = os.environ.get("ENVCAP_FUZZ_FIGURES")
    if path:
        Path(path).write_text(json.dumps(figs, indent=2) + "\n")
