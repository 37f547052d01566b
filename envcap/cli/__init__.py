"""The ``envcap`` command line.  Subcommands live beside this file in :mod:`envcap.cli`, one module each
(each has ``register(subparsers)``; a module without it is a helper, e.g. ``output_options``).

Errors in the input (bad files, bad arguments) print one line ``envcap: error: ...`` and exit
with status 2; nothing half-written is left behind (outputs are written atomically, see
:mod:`envcap.outputs`).  Ctrl-C exits with status 130 and SIGTERM with 143, after the same
clean-up, with one line ``envcap: interrupted`` / ``envcap: terminated``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys

from envcap import __version__
from envcap.cli.termination import EXIT_INTERRUPTED, EXIT_TERMINATED, Terminated, sigterm_raises

USER_ERRORS: tuple[type[BaseException], ...] = (ValueError, OSError, RuntimeError, KeyError)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="envcap",
        description="Street-level HDR environment probes: capture, cosine-lobe mip chains, parallax evaluation.",
    )
    parser.add_argument("--version", action="version", version=f"envcap {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        mod = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(mod, "register"):
            mod.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        with sigterm_raises():
            return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("envcap: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Terminated:
        print("envcap: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except USER_ERRORS as exc:
        msg = str(exc) if not isinstance(exc, KeyError) else f"missing key {exc}"
        print(f"envcap: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
