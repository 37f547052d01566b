"""Journey (issue 19): a user bakes their own scene, by a relative path, on a Dask cluster whose
scheduler and worker run in other directories, where that path means nothing.

The scene is the user's: a TOML in a folder of their working directory, naming a folder of PLY
meshes and a lat-long sky image, all by relative paths.  ``dask scheduler`` runs in one temporary
directory, ``dask worker`` in another (neither holds the user's folder), and the user types
``envcap capture town/town.toml --out ... --scheduler tcp://127.0.0.1:PORT``.  The city must have
the bytes of the same bake in one process (``--workers 0``), every file compared.  Before issue 19
every shard failed on the worker: ``FileNotFoundError('scene file town/town.toml not found')``.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from city_fixtures import tree
from dask_processes import Drained, free_port, stop_session

REPO = Path(__file__).resolve().parents[2]
SIZES = "--resolution 8 --spacing 10 --shard-mb 0"


def _user_scene(folder: Path) -> None:
    """The bundled ``imported`` scene as a user's own: ``town.toml`` naming ``blocks/`` (PLY
    boxes) and ``sky/overcast.exr`` (a 16 x 8 lat-long image), relative to the TOML."""
    import OpenEXR

    folder.mkdir()
    shutil.copytree(REPO / "city_scenes" / "imported_block", folder / "blocks")
    text = (REPO / "city_scenes" / "imported.toml").read_text()
    text = text.replace('file = "imported_block/"', 'file = "blocks/"')
    text, n = re.subn(r"\[sky\]\n(?:[^\[\n].*\n)*", '[sky]\ntype = "latlong"\nfile = "sky/overcast.exr"\n\n', text, count=1)
    assert n == 1 and 'file = "blocks/"' in text
    (folder / "town.toml").write_text(text)
    (folder / "sky").mkdir()
    y, x = np.mgrid[0:8, 0:16].astype(np.float32)
    rgb = np.stack([1 + x / 16, 1 + y / 8, np.full_like(x, 2.0)], -1)
    channels = {c: np.ascontiguousarray(rgb[..., i]) for i, c in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(
        str(folder / "sky" / "overcast.exr"))


@pytest.fixture
def cluster(terminal, tmp_path):
    """A ``dask scheduler`` and one ``dask worker`` (one thread), each started in a directory of
    its own (not the user's), each in its own session; both stopped, whatever happens."""
    port = free_port()
    (tmp_path / "scheduler").mkdir()
    (tmp_path / "worker").mkdir()
    started = []
    try:
        scheduler = terminal.start(f"dask scheduler --host 127.0.0.1 --port {port} --no-dashboard",
                                   cwd=tmp_path / "scheduler")
        started.append(scheduler)
        Drained(scheduler).wait_for("Scheduler at:", 60)
        worker = terminal.start(f"dask worker tcp://127.0.0.1:{port} --nworkers 1 --nthreads 1 --no-dashboard "
                                f"--local-directory {tmp_path / 'worker'}", cwd=tmp_path / "worker")
        started.append(worker)
        Drained(worker).wait_for("Registered to:", 60)
        yield f"tcp://127.0.0.1:{port}", tmp_path / "worker"
    finally:
        for proc in reversed(started):
            stop_session(proc)


@pytest.mark.slow
def test_a_relative_scene_bakes_on_a_cluster_in_other_directories_bit_for_bit(terminal, cluster):
    address, worker_dir = cluster
    _user_scene(terminal.cwd / "town")
    assert not (worker_dir / "town").exists()                     # the path means nothing where the worker runs

    dask = terminal.run(f"envcap capture town/town.toml --out city_dask --scheduler {address} {SIZES}")
    one = terminal.run(f"envcap capture town/town.toml --out city_one --workers 0 {SIZES}")

    assert "1 shard(s) on 1 worker(s)" in dask.stderr, dask.stderr
    assert tree(terminal.cwd / "city_dask") == tree(terminal.cwd / "city_one")
    assert {p.name for p in (terminal.cwd / "city_dask").iterdir()} >= {"city.json", "street_map.ktx2", "shards"}
    assert sorted(p.name for p in terminal.cwd.iterdir()) == ["city_dask", "city_one", "town"]
    assert not any(worker_dir.rglob("*.ktx2")), "the worker left a shard on its own disk"
