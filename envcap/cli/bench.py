"""``envcap bench NAME``: run one benchmark from :mod:`envcap.benchmarks`."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
from collections.abc import Callable

import envcap.benchmarks
from envcap.cli.output_options import add_force_argument
from envcap.outputs import claim_output_dir

BenchmarkRun = Callable[[argparse.Namespace], int | None]


def with_claimed_out(run: BenchmarkRun) -> BenchmarkRun:
    """Claim the benchmark's ``--out`` before it runs (see :mod:`envcap.outputs`); the benchmark
    then writes through the claim, which stands in for the path in ``args.out``."""
    def claimed(args: argparse.Namespace) -> int | None:
        if getattr(args, "out", None) is None:  # a benchmark that writes no files
            return run(args)
        with claim_output_dir(args.out, kind="benchmark", force=args.force) as out:
            args.out = out
            return run(args)
    return claimed


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
        add_force_argument(bp)
        bp.set_defaults(func=with_claimed_out(mod.run))
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
