"""``envcap view DIR``: serve a probe set (and its evaluation report, if any) to a WebGL2 page on
127.0.0.1 and print the address (docs/viewer.md).  ``DIR`` is a probe set, a city probe set
(``city.json``) or a directory holding one, e.g. ``envcap demo``'s output or an ``envcap export
web`` site (:mod:`envcap.viewer.site_dir`); ``--avatar FILE``: the crowd's avatar (``envcap
avatar``'s output; default the bundled walker).  Serves until Ctrl-C / SIGTERM."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from envcap.crowd.inputs import read_avatar
from envcap.viewer.server import ViewerServer
from envcap.viewer.site_dir import open_site


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("view", help="serve a probe set to a WebGL2 viewer page on 127.0.0.1")
    p.add_argument("probes", type=Path, metavar="DIR",
                   help="probe-set directory with probes_atlas.ktx2 ('envcap capture ... --webgl2', 'envcap demo'), "
                        "a city directory (city.json), or a directory holding one (envcap demo's --out)")
    p.add_argument("--report", type=Path, metavar="DIR",
                   help="evaluation report directory ('envcap evaluate --out'); default: a directory holding "
                        "report.json in or beside the probe set")
    p.add_argument("--avatar", type=Path, metavar="FILE",
                   help="the crowd's avatar, a file 'envcap avatar' wrote (default: the bundled walker)")
    p.add_argument("--port", type=int, default=0, help="TCP port on 127.0.0.1 (default 0: a free one)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.avatar is not None:
        read_avatar(args.avatar)   # checked before serving: a bad file is one line here, not a failed request
    site = open_site(args.probes, args.report, avatar=args.avatar)
    server = ViewerServer(site, args.port)
    print(f"envcap viewer: {server.url}  (probe set {site.probe_dir}"
          + (f", report {site.report_dir}" if site.report_dir else "") + "; Ctrl-C stops)", flush=True)
    try:
        server.serve_forever()
    finally:
        server.server_close()
        print("envcap viewer: stopped", file=sys.stderr)
    return 0
