"""Large lat-long input: peak memory and time of ``envcap prefilter`` against the image's own size.

Writes a synthetic ``H x 2H`` float32 RGB lat-long EXR (a smooth sky gradient over a darker
ground plus a bright sun disk) to a temporary folder that is removed afterwards, then runs
``envcap prefilter IN --out D --size N`` in a child process for each ``N`` and records the child's
peak resident memory (``wait4`` ``ru_maxrss``) and wall time, the read/prefilter/write split from
``chain.json``, and the relative error of the level-0 cube's flux ``sum(L omega)`` against the
image's own (float64).  The default, ``--height 8192``, is the 16384 x 8192 case of issue 9
(image 1.5 GiB as float32 RGB); it needs about 80 s and 3 GiB per size on 2 cores.

    envcap bench latlong --out bench_latlong [--height 8192] [--sizes 64 256]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

import envcap
from envcap.core import cube as cm
from envcap.core.budget import format_bytes
from envcap.formats.ktx2 import read_ktx2
from envcap.outputs import atomic_output_dir

SUN_DIRECTION = (math.cos(math.radians(35)) * math.sin(math.radians(120)), math.sin(math.radians(35)),
                 math.cos(math.radians(35)) * math.cos(math.radians(120)))
SUN_RADIUS_DEG = 0.5
SUN_RADIANCE = 1.0e6


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="output directory (latlong.json)")
    p.add_argument("--height", type=int, default=8192, help="lat-long height H; width 2H (default 8192)")
    p.add_argument("--sizes", type=int, nargs="+", default=[64, 256], help="cube face sizes --size (default 64 256)")
    p.add_argument("--quality", default="default", choices=["fast", "default", "high"], help="prefilter quality")


def synthetic_latlong_band(y0: int, y1: int, h: int) -> NDArray[np.float32]:
    """Rows ``y0:y1`` of the synthetic ``h x 2h`` sky: ``(y1 - y0, 2h, 3)`` float32 radiance."""
    w = 2 * h
    lat = -math.pi * ((np.arange(y0, y1) + 0.5) / h - 0.5)
    lon = -2.0 * math.pi * ((np.arange(w) + 0.5) / w - 0.5)
    cl = np.cos(lat)[:, None]
    d = np.stack(np.broadcast_arrays(np.sin(lon)[None, :] * cl, np.sin(lat)[:, None], np.cos(lon)[None, :] * cl), -1)
    up = d[..., 1:2]
    sky = (300.0 + 700.0 * np.clip(up, 0, 1)) * np.array([0.55, 0.7, 1.0]) * (1 + 0.2 * d[..., 0:1])
    ground = 150.0 * np.array([0.45, 0.4, 0.35]) * (1.2 + 0.2 * d[..., 2:3])
    out = np.where(up >= 0, sky, ground)
    sun = d @ np.asarray(SUN_DIRECTION) > math.cos(math.radians(SUN_RADIUS_DEG))
    out[sun] = SUN_RADIANCE
    return out.astype(np.float32)


def write_synthetic_exr(path: Path, h: int) -> float:
    """Write the synthetic sky as a float32 RGB lat-long EXR; returns its luminance-free flux
    ``sum over pixels and channels of L omega`` (float64), the reference for the cube's."""
    import OpenEXR

    w = 2 * h
    img = np.empty((h, w, 3), np.float32)
    half = 0.5 * math.pi / h
    flux = 0.0
    rows = max(1, (1 << 21) // w)
    for y0 in range(0, h, rows):
        y1 = min(h, y0 + rows)
        img[y0:y1] = synthetic_latlong_band(y0, y1, h)
        mid = 0.5 * math.pi - (np.arange(y0, y1) + 0.5) * math.pi / h
        omega = (2.0 * math.pi / w) * 2.0 * np.cos(mid) * math.sin(half)
        flux += float(np.einsum("yxc,y->", img[y0:y1].astype(np.float64), omega))
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
                  "envmap": OpenEXR.ENVMAP_LATLONG}, {"RGB": img}).write(str(path))
    return flux


def run_prefilter(inp: Path, out: Path, size: int, quality: str) -> dict:
    """Run ``envcap prefilter`` in a child process; its wall time, peak RSS and chain.json timings."""
    env = dict(os.environ)
    root = str(Path(envcap.__file__).resolve().parents[1])
    env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [sys.executable, "-m", "envcap", "prefilter", str(inp), "--out", str(out), "--size", str(size),
           "--quality", quality]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    stderr = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.stdout:
        proc.stdout.close()
    if proc.stderr:
        proc.stderr.close()
    if proc.returncode != 0:
        raise RuntimeError(f"envcap prefilter --size {size} failed ({proc.returncode}): {stderr.strip()[-300:]}")
    manifest = json.loads((out / "chain.json").read_text())
    return {"size": size, "seconds": seconds, "peak_rss_bytes": usage.ru_maxrss * 1024,
            "timings_s": manifest["timings_s"]}


def cube_flux(path: Path) -> float:
    """``sum(L omega)`` over R, G, B of level 0 of a prefilter output's ``chain.ktx2`` (float64)."""
    levels, _ = read_ktx2(path)
    c0 = np.asarray(levels[0], np.float64)
    return float(np.einsum("fyxc,fyx->", c0[..., :3], cm.texel_solid_angles(c0.shape[1])))


def run(args: argparse.Namespace) -> int:
    h = int(args.height)
    if h < 2:
        raise ValueError(f"--height must be >= 2, got {h}")
    image_bytes = h * 2 * h * 3 * 4
    result: dict = {"height": h, "width": 2 * h, "image_float32_rgb_bytes": image_bytes,
                    "sun": {"direction": SUN_DIRECTION, "radius_deg": SUN_RADIUS_DEG, "radiance": SUN_RADIANCE},
                    "quality": args.quality, "runs": []}
    with tempfile.TemporaryDirectory(prefix="envcap-bench-latlong-") as tmpdir:
        tmp = Path(tmpdir)
        t0 = time.perf_counter()
        flux = write_synthetic_exr(tmp / "latlong.exr", h)
        result["write_input_seconds"] = time.perf_counter() - t0
        result["input_file_bytes"] = (tmp / "latlong.exr").stat().st_size
        for size in args.sizes:
            rec = run_prefilter(tmp / "latlong.exr", tmp / f"out_{size}", int(size), args.quality)
            rec["peak_rss_over_image"] = rec["peak_rss_bytes"] / image_bytes
            rec["flux_rel_error"] = cube_flux(tmp / f"out_{size}" / "chain.ktx2") / flux - 1.0
            result["runs"].append(rec)
            print(f"{2 * h}x{h} -> --size {size}: {rec['seconds']:.1f} s (read+resample {rec['timings_s']['read']:.1f} s), "
                  f"peak RSS {format_bytes(rec['peak_rss_bytes'])} = {rec['peak_rss_over_image']:.2f} x the image "
                  f"({format_bytes(image_bytes)}), flux error {rec['flux_rel_error']:.1e}", flush=True)
    with atomic_output_dir(args.out) as out:
        (out / "latlong.json").write_text(json.dumps(result, indent=2))
    return 0
