"""``envcap bench NAME``: run one benchmark from :mod:`envcap.benchmarks`."""

from __future__ import annotations

import argparse
import importlib
import pkgutil

import envcap.benchmarks


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="run a benchmark (what accuracy costs in time)")
    names = sorted(m.name for m in pkgutil.iter_modules(envcap.benchmarks.__path__))
    bsub = p.add_subparsers(dest="benchmark", metavar="NAME")
    for name in names:
        mod = importlib.import_module(f"envcap.benchmarks.{name}")
        if not hasattr(mod, "add_arguments"):  # a helper module (e.g. benchmarks.inputs), not a benchmark
            continue
        doc = (mod.__doc__ or "").strip().splitlines()
        bp = bsub.add_parser(name, help=doc[0] if doc else name)
        mod.add_arguments(bp)
        bp.set_defaults(func=mod.run)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
