"""webgl2: cost of each parallax method in the viewer's WebGL2 runtime, as a ratio to a plain lookup in the same page.

``envcap bench webgl2 --probes DIR --out OUT`` serves the probe set (baked with ``--webgl2``) with
:mod:`envcap.viewer`, opens the page in headless Chromium (:mod:`envcap.viewer.browser`; WebGL2
on SwiftShader, a CPU rasterizer: absolute times are not a GPU's, ratios are the point) and
times ``--repeats`` full passes of ``--size``² lookups per mode (``window.envcap.bench``: median of
the passes, each ended by a 1-pixel ``readPixels`` that waits for it).  Lookups: points spread
over the first street between its first and last probe (in the street's frame: any angle), directions uniform on the sphere, lobe powers
log-uniform in [1, 10^4].  Modes: ``plain`` (one face-atlas lookup, ``envcap_face_atlas_lod``: the
WebGL2 counterpart of ``textureLod(samplerCubeArray, ...)``), ``sky`` (one hardware cube-map
``textureLod``), then every method the page offers.  Writes ``webgl2.json`` and prints a
Markdown table (``docs/viewer.md``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from envcap.outputs import atomic_output_dir
from envcap.viewer.browser import Chromium
from envcap.viewer.server import serve
from envcap.viewer.site import ViewerSite, viewer_methods


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--probes", required=True, type=Path, help="probe-set directory with probes_atlas.ktx2")
    parser.add_argument("--out", required=True, help="output directory (webgl2.json)")
    parser.add_argument("--size", type=int, default=256, help="lookups per pass: size x size (default 256)")
    parser.add_argument("--repeats", type=int, default=9, help="timed passes per mode (default 9)")


def table(result: dict) -> str:
    """The Markdown table of a result: mode, ms per pass, ns per lookup, ratio to plain."""
    rows = ["| mode | ms / pass | ns / lookup | time / plain |", "| --- | ---: | ---: | ---: |"]
    n = result["lookups"]
    for k, ms in result["median_ms"].items():
        rows.append(f"| `{k}` | {ms:.2f} | {ms * 1e6 / n:.1f} | {result['ratio_to_plain'][k]:.2f} |")
    return "\n".join(rows)


def run(args: argparse.Namespace) -> int:
    if args.size < 1 or args.repeats < 1:
        raise ValueError("--size and --repeats must be >= 1")
    site = ViewerSite.open(args.probes)
    server, thread = serve(site)
    modes = ["plain", "sky"] + [m["name"] for m in viewer_methods()]
    try:
        with Chromium(400, 300, timeout=600.0) as b:
            b.goto(server.url)
            b.evaluate("window.envcap.ready")
            renderer = b.evaluate("(() => { const g = window.envcap.viewer.gl, e = g.getExtension('WEBGL_debug_renderer_info');"
                                  " return e ? g.getParameter(e.UNMASKED_RENDERER_WEBGL) : g.getParameter(g.RENDERER); })()")
            med = b.evaluate(f"window.envcap.bench({json.dumps(modes)}, {args.size}, {args.size}, {args.repeats})")
            if b.errors:
                raise RuntimeError("the page reported errors: " + "; ".join(b.errors))
    finally:
        server.shutdown()
        server.server_close()
    result = {"renderer": renderer, "probe_set": str(site.probe_dir), "lookups": args.size * args.size,
              "repeats": args.repeats, "median_ms": med, "ratio_to_plain": {k: v / med["plain"] for k, v in med.items()}}
    with atomic_output_dir(args.out) as tmp:
        (Path(tmp) / "webgl2.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"renderer: {renderer}; {args.size}x{args.size} lookups, median of {args.repeats} passes")
    print(table(result))
    return 0
