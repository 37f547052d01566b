"""``envcap prefilter IN --out DIR [--size N] [--quality Q]``: an environment map to a cosine-lobe chain.

``IN`` is an OpenEXR cube env map (``envcap.formats.exr_cube.read_exr_cube``) or a 2:1 lat-long
HDR/EXR (``envcap.core.latlong.load_latlong``, resampled with ``latlong_to_cube``).  ``DIR`` gets,
atomically (all or nothing):

* ``chain.ktx2``: plain cube map, RGBA32F, every level of the chain (``envcap.formats.ktx2``), with
  only the key/values the KTX 2.0 specification defines: what its levels are (the lobe ladder) is
  in ``chain.json`` (before issue 19 envcap also wrote it into the file, as the custom key ``envcap.lobes``);
* ``level_KK.exr``: one OpenEXR cube env map per level, for inspection (half floats when every
  value fits, float32 otherwise);
* ``chain.json``: the lobe ladder (``LobeLadder.to_manifest()``: sizes, powers, z(w) rule),
  the input, the quality and the timings in seconds;
* ``.envcap-output``: the marker of an envcap output (:mod:`envcap.outputs.marker`).

``DIR`` is claimed before the input is read (:mod:`envcap.outputs.claim`): it may not hold ``IN``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from envcap.cli.output_options import add_force_argument
from envcap.core.input_path import require_file
from envcap.core.latlong import latlong_to_cube, load_latlong
from envcap.core.lobes import lobe_ladder
from envcap.formats.exr_cube import ExrDataError, read_exr_cube, write_exr_cube
from envcap.formats.ktx2 import write_ktx2
from envcap.outputs import atomic_output_dir, claim_output_dir
from envcap.prefilter import QUALITIES, omega_box_pyramid, prefilter_chain


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("prefilter", help="filter an environment map (EXR cube or lat-long HDR/EXR) into a cosine-lobe mip chain")
    p.add_argument("input", metavar="IN", help="OpenEXR cube env map, or a 2:1 lat-long .exr/.hdr")
    p.add_argument("--out", required=True, help="output directory (replaced atomically)")
    p.add_argument("--size", type=int, default=None,
                   help="face size of level 0 (default: the cube's own size; for lat-long, a power of two near width/4)")
    p.add_argument("--quality", default="default", choices=list(QUALITIES),
                   help="prefilter quality (see docs/prefilter.md); default: default")
    add_force_argument(p)
    p.set_defaults(func=run)


def load_environment(path: str | Path, size: int | None) -> tuple[NDArray[np.float32], str]:
    """Read ``path`` as an RGBA cube ``(6, N, N, 4)`` float32 and say which kind it was.

    Raises ``FileNotFoundError`` for a missing file, ``ValueError`` for a file that is neither an
    OpenEXR cube env map nor a 2:1 lat-long image (naming both reasons), for a truncated EXR, for
    NaN/Inf or negative texels, and for a bad ``size`` (< 1, or not ``N >> k`` of a cube input).
    """
    path = require_file(path, "input file")
    if size is not None and (isinstance(size, bool) or int(size) < 1):
        raise ValueError(f"--size must be a positive integer, got {size}")
    try:
        rgba, _ = read_exr_cube(path)
        kind = "exr-cube"
    except ExrDataError:  # truncated/corrupt, NaN/Inf or negative radiance: no other reader helps
        raise
    except ValueError as cube_err:
        try:
            img = load_latlong(path)
        except ValueError as ll_err:
            raise ValueError(f"{path} is neither an OpenEXR cube env map ({cube_err}) "
                             f"nor a lat-long image ({ll_err})") from None
        n = size if size is not None else max(1, 1 << max(0, int(round(np.log2(max(img.shape[1] // 4, 1))))))
        rgb = latlong_to_cube(img, int(n))
        rgba = np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,), np.float32)], -1)
        return rgba, "latlong"
    n0 = rgba.shape[1]
    if size is None or size == n0:
        return rgba, kind
    k = 0
    while (n0 >> k) > size and (n0 >> k) % 2 == 0:
        k += 1
    if (n0 >> k) != size:
        raise ValueError(f"--size {size} is not the cube's size {n0} halved k times (a cube is only reduced, by exact 2x2 box steps)")
    return omega_box_pyramid(rgba, k + 1)[k].astype(np.float32), kind


def run(args: argparse.Namespace) -> int:
    with claim_output_dir(args.out, kind="prefilter-chain", inputs=[args.input], force=args.force) as out:
        t0 = time.perf_counter()
        cube, kind = load_environment(args.input, args.size)
        t_read = time.perf_counter() - t0
        ladder = lobe_ladder(cube.shape[1])
        t0 = time.perf_counter()
        chain = prefilter_chain(cube, ladder, quality=args.quality)
        t_filter = time.perf_counter() - t0
        t0 = time.perf_counter()
        with atomic_output_dir(out) as tmp:
            write_ktx2(tmp / "chain.ktx2", [np.ascontiguousarray(c, np.float32) for c in chain], layered=False,
                       fmt="rgba32f")
            for k, lv in enumerate(chain):
                write_exr_cube(tmp / f"level_{k:02d}.exr", lv, half=None)
            manifest = {
                "input": str(args.input),
                "input_kind": kind,
                "quality": args.quality,
                "lobes": ladder.to_manifest(),
                "sizes": [int(s) for s in ladder.sizes],
                "levels": [f"level_{k:02d}.exr" for k in range(ladder.levels)],
                "ktx2": "chain.ktx2",
                "timings_s": {"read": t_read, "prefilter": t_filter, "write": time.perf_counter() - t0},
            }
            (tmp / "chain.json").write_text(json.dumps(manifest, indent=2))
    print(f"{args.out}: {ladder.levels} levels, {cube.shape[1]}^2 per face, prefilter {t_filter:.2f} s")
    return 0
