"""City bake at scale: one process against a Dask LocalCluster, bit-identical, and killed-and-resumed.

The city is the bundled ``canyon`` street tiled ``--streets`` times side by side (parallel
streets ``--pitch`` m apart along z, each ``--length`` m long, its own building seeds): a stand-in
until a generated city exists.  Measured, each run in a fresh child process (so peak memory is
the bake's own):

* ``one``: ``bake_city(workers=0)``: every shard in one process (the simplest correct method);
* ``dask``: ``bake_city(workers=--workers)``: a ``LocalCluster`` of worker processes (each keeps
  one EGL context and loads the scene once), the wall time including the cluster's start
  (``dask_start_s``: until the workers are up);
* ``resumed``: the ``one`` run SIGKILLed at ``--kills`` random points (seeded: a random time,
  up to one shard's mean bake time, after a random shard still to do is on disk), resumed after
  each kill, then run to completion.

The children run a snapshot of envcap's code taken at the start (shard keys include a digest of
the code, so an edit to the working tree during the run would make other shards).  Reports wall
times, probes/s, the speed-up, CPU seconds (the single process; the Dask workers), whether ``dask`` and ``resumed`` are bit-identical
to ``one`` (every file compared), peak RSS of the single process and of each Dask worker, bytes
on disk per shard and per probe, and the load average seen.  Writes ``city.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from envcap.city.bake import bake_city
from envcap.city.plan import BakeSettings, probe_bytes
from envcap.core.resources import city_scenes_dir, shaders_dir
from envcap.formats.registry import default_writer_names
from envcap.outputs import atomic_output_dir
from envcap.scene.bundled import scene_path
from envcap.scene.parse import read_toml


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, help="output directory (city.json)")
    parser.add_argument("--streets", type=int, default=6, help="parallel canyon streets (default 6)")
    parser.add_argument("--length", type=float, default=200.0, help="street length in m (default 200)")
    parser.add_argument("--pitch", type=float, default=100.0, help="distance between street centre lines, m (default 100)")
    parser.add_argument("--resolution", type=int, default=32, help="face size N (default 32)")
    parser.add_argument("--spacing", type=float, default=10.0, help="probe spacing in m (default 10)")
    parser.add_argument("--workers", type=int, default=2, help="Dask worker processes (default 2)")
    parser.add_argument("--shard-mb", type=float, default=0.0, help="shard budget, MB (default 0: one per street)")
    parser.add_argument("--kills", type=int, default=3, help="random SIGKILLs of the resumed run (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the kill points")


def tiled_canyon(streets: int, length: float, pitch: float) -> dict[str, Any]:
    """The scene table of ``streets`` copies of canyon's street, ``pitch`` m apart along z."""
    data = read_toml(scene_path("canyon"))
    base = data["streets"][0]
    tiles = []
    for i in range(streets):
        st = json.loads(json.dumps(base))
        st.update(name=f"canyon_{i:03d}", start=-length / 2, end=length / 2, cross=i * pitch)
        st["side_min"]["seed"], st["side_max"]["seed"] = 2 * i + 1, 2 * i + 2
        tiles.append(st)
    data.update(name="tiled_canyon", streets=tiles,
                description=f"{streets} canyon streets of {length:g} m, {pitch:g} m apart (envcap bench city)")
    data["ground"]["extent"] = max(float(data["ground"].get("extent", 0)), 2 * (length + streets * pitch))
    return data


def run_child(spec_path: str) -> None:
    """Child process entry: bake the city of a spec JSON, print wall time, peak RSS, stats."""
    spec = json.loads(Path(spec_path).read_text())
    t0 = time.perf_counter()
    r = bake_city(spec["scene"], spec["out"], BakeSettings(**spec["settings"]), workers=spec["workers"],
                  budget_mb=spec["shard_mb"])
    use = resource.getrusage(resource.RUSAGE_SELF)
    print(json.dumps({"wall_s": time.perf_counter() - t0, "baked": r.baked, "skipped": r.skipped,
                      "dask_start_s": r.dask_start_s, "peak_rss_bytes": use.ru_maxrss * 1024,
                      "cpu_s": use.ru_utime + use.ru_stime, "workers": r.workers}))


def _shards_done(city: Path) -> int:
    return len(list((city / "shards").glob("[0-9]*"))) if (city / "shards").is_dir() else 0


def snapshot_code(dest: Path) -> Path:
    """Copy envcap's package, shaders and bundled scenes under ``dest`` (what the children import:
    edits to the working tree during the benchmark do not reach them); return ``dest``."""
    pkg = Path(__file__).resolve().parents[1]
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(pkg, dest / "envcap", ignore=skip)
    for name, where in (("shaders", shaders_dir()), ("city_scenes", city_scenes_dir())):
        if not (dest / "envcap" / name).is_dir():
            shutil.copytree(where, dest / name, ignore=skip)
    return dest


def _child(spec: dict[str, Any], work: Path, kill_at: tuple[int, float] | None = None) -> dict[str, Any] | None:
    """Run ``run_child`` on ``spec`` in a new process; with ``kill_at = (k, s)``, SIGKILL it ``s``
    seconds after its ``k``-th shard is on disk (None when killed)."""
    path = work / f"spec-{hashlib.sha1(json.dumps(spec).encode()).hexdigest()[:8]}.json"
    path.write_text(json.dumps(spec))
    code = "import sys; from envcap.benchmarks.city import run_child; run_child(sys.argv[1])"
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as log:
        proc = subprocess.Popen([sys.executable, "-c", code, str(path)], stdout=log, stderr=subprocess.DEVNULL,
                                start_new_session=True, cwd=work, env=dict(os.environ, PYTHONPATH=str(work / "code")))
        seen = None
        while proc.poll() is None:
            if kill_at is not None and seen is None and _shards_done(Path(spec["out"])) >= kill_at[0]:
                seen = time.perf_counter()
            if seen is not None and time.perf_counter() - seen >= kill_at[1]:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                return None
            time.sleep(0.005)
        if proc.returncode != 0:
            raise RuntimeError(f"city bake child failed (status {proc.returncode})")
        log.seek(0)
        out = log.read().decode()
    return {**json.loads(out.strip().splitlines()[-1]), "process_s": time.perf_counter() - t0}


def _files(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _differ(got: dict[str, str], ref: dict[str, str]) -> list[str]:
    """Paths (at most 20) whose bytes differ, or that only one of the two trees has."""
    return sorted(k for k in set(got) | set(ref) if got.get(k) != ref.get(k))[:20]


def run(args: argparse.Namespace) -> int:
    if min(args.streets, args.resolution, args.workers) < 1 or args.kills < 0:
        raise ValueError("--streets, --resolution and --workers must be >= 1, --kills >= 0")
    scene = tiled_canyon(args.streets, args.length, args.pitch)
    settings = dict(resolution=args.resolution, spacing=args.spacing, writers=sorted(default_writer_names()))
    load = os.getloadavg()
    work = Path(tempfile.mkdtemp(prefix="envcap-bench-city-"))
    try:
        snapshot_code(work / "code")
        def spec(name: str, workers: int) -> dict[str, Any]:
            return {"scene": scene, "out": str(work / name), "settings": settings, "workers": workers,
                    "shard_mb": args.shard_mb}

        one = _child(spec("one", 0), work)
        dask = _child(spec("dask", args.workers), work)
        rng = random.Random(args.seed)
        kills = []
        total = len(list((work / "one" / "shards").iterdir()))
        per_shard = one["wall_s"] / total
        for _ in range(args.kills):
            done = _shards_done(work / "resumed")
            if done >= total:
                break
            # a random point: after a random shard boundary still ahead, a random time into the next shard
            k, s = rng.randint(done, total - 1), rng.uniform(0.0, per_shard)
            finished = _child(spec("resumed", 0), work, kill_at=(k, s)) is not None
            kills.append({"after_shard": k, "after_s": round(s, 3), "shards_done_before": done,
                          "shards_done_after": _shards_done(work / "resumed"), "completed": finished})
        resumed = _child(spec("resumed", 0), work)
        ref = _files(work / "one")
        index = json.loads((work / "one" / "city.json").read_text())
        probes = index["layer_count"]
        shard_bytes = [sum((work / "one" / sh["path"] / f).stat().st_size for f in ("probes.ktx2", "sky.ktx2"))
                       for sh in index["shards"]]
        out = {
            "scene": scene["description"], "probes": probes, "streets": args.streets, "shards": len(index["shards"]),
            "settings": settings, "workers": args.workers, "load_average_before": load,
            "one": {**one, "probes_per_s": probes / one["wall_s"]},
            "dask": {**dask, "probes_per_s": probes / dask["wall_s"],
                     "cpu_s_workers": sum(w["cpu_s"] for w in dask["workers"].values())},
            "speedup_dask_over_one": one["wall_s"] / dask["wall_s"],
            "dask_identical_to_one": _files(work / "dask") == ref,
            "kills": kills, "resumed": resumed, "resumed_identical_to_one": _files(work / "resumed") == ref,
            "differ": {name: _differ(_files(work / name), ref) for name in ("dask", "resumed")},
            "bytes": {"probe_ktx2_per_probe": probe_bytes(args.resolution), "ktx2_per_shard": shard_bytes,
                      "city_dir": sum((work / "one" / f).stat().st_size for f in ref)},
        }
    finally:
        shutil.rmtree(work, ignore_errors=True)
    with atomic_output_dir(args.out) as d:
        (Path(d) / "city.json").write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps({k: out[k] for k in ("probes", "shards", "speedup_dask_over_one", "dask_identical_to_one",
                                           "resumed_identical_to_one")}))
    print(f"one process {out['one']['wall_s']:.1f} s, dask x{args.workers} {out['dask']['wall_s']:.1f} s")
    return 0
