"""`pip install .` works from another directory: shaders and bundled scenes ship inside the package."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow  # a pip install: ~5 s idle
def test_installed_package_finds_shaders_and_scenes(tmp_path):
    # Install from a copy without build leftovers: pip builds in the source tree, and a stale
    # build/lib (e.g. of an older layout) would otherwise ship too, as it would not from a clone.
    src = tmp_path / "src"
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".git", "build", "dist", "*.egg-info", "__pycache__",
                                                             ".pytest_cache", "out", ".venv"))
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
         "--target", str(target), str(src)],
        check=True, capture_output=True, timeout=300,
    )
    code = (
        "import envcap, envcap.core.resources as r, envcap.scene as s;"
        "assert envcap.__file__.startswith(%r), envcap.__file__;"
        "print(r.shaders_dir()); print(r.city_scenes_dir());"
        "print(sorted(p.relative_to(r.shaders_dir()).as_posix() for p in r.shaders_dir().rglob('*.glsl')));"
        "import pathlib; pkg = pathlib.Path(envcap.__file__).parent;"
        "print(sorted(q for q in (p.relative_to(pkg).as_posix() for p in pkg.rglob('*.py'))"
        "             if q.split('/')[0] not in ('shaders', 'city_scenes')));"
        "print(len(r.shader_source('runtime/envcap_runtime.glsl')) > 0);"
        "print(sorted(n for n, _ in s.list_scenes()));"
        "print(s.load_scene('imported').mesh.triangle_count > 0);"
        "import envcap.viewer.site as v;"
        "print(sorted(p.relative_to(v.WEB_DIR).as_posix() for p in v.WEB_DIR.rglob('*') if p.is_file()))"
    ) % str(target)
    env = {"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].startswith(str(target)) and lines[1].startswith(str(target))
    shipped = sorted(p.relative_to(REPO / "shaders").as_posix() for p in (REPO / "shaders").rglob("*.glsl"))
    assert lines[2] == repr(shipped), "the installed shaders/ tree differs from the checkout's"
    modules = sorted(p.relative_to(REPO / "envcap").as_posix() for p in (REPO / "envcap").rglob("*.py"))
    assert lines[3] == repr(modules), "pyproject.toml's package list misses a package"
    assert lines[4] == "True" and "canyon" in lines[5] and lines[6] == "True"
    web = sorted(p.relative_to(REPO / "envcap" / "viewer" / "web").as_posix()
                 for p in (REPO / "envcap" / "viewer" / "web").rglob("*") if p.is_file())
    assert lines[7] == repr(web), "the installed viewer pages (three.js included: envcap export web copies it) differ"
