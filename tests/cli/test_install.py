"""`pip install .` works from another directory: shaders and bundled scenes ship inside the package."""

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_installed_package_finds_shaders_and_scenes(tmp_path):
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
         "--target", str(target), str(REPO)],
        check=True, capture_output=True, timeout=300,
    )
    code = (
        "import envcap, envcap.core.resources as r, envcap.scene as s;"
        "assert envcap.__file__.startswith(%r), envcap.__file__;"
        "print(r.shaders_dir()); print(r.city_scenes_dir());"
        "print(len(r.shader_source('envcap_runtime.glsl')) > 0);"
        "print(sorted(n for n, _ in s.list_scenes()));"
        "print(s.load_scene('imported').mesh.triangle_count > 0)"
    ) % str(target)
    env = {"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].startswith(str(target)) and lines[1].startswith(str(target))
    assert lines[2] == "True" and "canyon" in lines[3] and lines[4] == "True"
