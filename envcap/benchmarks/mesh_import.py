"""City mesh import: time and peak memory per triangle at 10^5 and 10^6 triangles.

Writes the generated city (``envcap.scene.city_layout``, one Z-up PLY per building in projected
coordinates, some wound inward) with every facade split into ``n x n`` quads to reach each size,
into a temporary folder that is removed afterwards.  For each size, a child process runs
``import_meshes`` on the PLY files (transform, parts, winding fix, flat shading) and records wall
time, the peak of traced allocations (``tracemalloc``: numpy's arrays included) over the imported
triangle count, and the child's peak resident memory above its level before the import
(``ru_maxrss``).  The reference in the same child: loading the same files with trimesh alone
and concatenating their vertices and faces (no envcap processing), time and peak.

    envcap bench mesh_import --out bench_import [--cells 10 31]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from envcap.outputs import atomic_output_dir
from envcap.scene.city_files import write_city
from envcap.scene.city_layout import CitySpec, generate_city_layout

CHILD = r"""
import json, resource, sys, time, tracemalloc
from pathlib import Path
import numpy as np, trimesh
from envcap.scene.mesh_import import import_meshes
root = Path(sys.argv[1]); truth = json.loads((root / "truth.json").read_text())
files = sorted((root / "buildings").glob("*.ply"))
def measure(fn):
    tracemalloc.start(); rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter(); out = fn(); dt = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]; tracemalloc.stop()
    return out, dt, peak, (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) * 1024
def plain():
    ms = [trimesh.load(str(f), process=False) for f in files]
    return np.concatenate([m.vertices for m in ms]), np.concatenate([m.faces for m in ms])
(v, f), t_ref, p_ref, _ = measure(plain)
del v, f
(mesh, report), t, p, rss = measure(lambda: import_meshes(files, up_axis="z", offset=truth["frame"]["offset"]))
n = mesh.triangle_count
print(json.dumps({"triangles": n, "files": len(files), "flipped": report.flipped, "seconds": t, "peak_bytes": p,
                  "peak_bytes_per_triangle": p / n, "rss_growth_bytes_per_triangle": rss / n,
                  "trimesh_only_seconds": t_ref, "trimesh_only_peak_bytes_per_triangle": p_ref / n}))
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (mesh_import.json, mesh_import.md)")
    p.add_argument("--cells", type=int, nargs="+", default=[10, 31],
                   help="facade quads per side n (n x n per facade): 10 ~ 1.3e5, 31 ~ 1.3e6 triangles")


def run(args: argparse.Namespace) -> int:
    rows = []
    with tempfile.TemporaryDirectory(prefix="envcap-bench-import-") as tmp:
        for cells in args.cells:
            city = Path(tmp) / f"city_{cells}"
            write_city(generate_city_layout(CitySpec(facade_cells=cells)), city)
            out = subprocess.run([sys.executable, "-c", CHILD, str(city)], capture_output=True, text=True, check=True)
            row = {"cells": cells, **json.loads(out.stdout.strip().splitlines()[-1])}
            rows.append(row)
            print(f"{row['triangles']:>9} triangles ({row['files']} files): {row['seconds']:.2f} s, "
                  f"peak {row['peak_bytes_per_triangle']:.0f} B/triangle (RSS growth "
                  f"{row['rss_growth_bytes_per_triangle']:.0f}); trimesh alone {row['trimesh_only_seconds']:.2f} s "
                  f"({row['seconds'] / row['trimesh_only_seconds']:.1f}x)", flush=True)
    lines = ["| triangles | files | import (s) | peak (B/triangle) | RSS growth (B/triangle) | trimesh load alone (s) | ratio |",
             "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    lines += [f"| {r['triangles']:,} | {r['files']} | {r['seconds']:.2f} | {r['peak_bytes_per_triangle']:.0f} | "
              f"{r['rss_growth_bytes_per_triangle']:.0f} | {r['trimesh_only_seconds']:.2f} | "
              f"{r['seconds'] / r['trimesh_only_seconds']:.1f} |" for r in rows]
    with atomic_output_dir(args.out) as d:
        (d / "mesh_import.json").write_text(json.dumps(rows, indent=1) + "\n")
        (d / "mesh_import.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0
