"""The ``envcap`` command line.  Subcommands live beside this file in :mod:`envcap.cli`, one module each
(each has ``register(subparsers)``; a module without it is a helper, e.g. ``output_options``).

Errors in the input (bad files, bad arguments) print one line ``envcap: error: ...`` and exit
with status 2; nothing half-written is left behind (outputs are written atomically, see
:mod:`envcap.outputs`).  Ctrl-C exits with status 130 and SIGTERM with 143, after the same
clean-up, with one line ``envcap: interrupted`` / ``envcap: terminated``.

The error line is the exception's text (:func:`error_text`): an ``OSError`` that carries only the
system's wording (``[Errno 2] No such file or directory: 'x'``) becomes ``x: no such file or
directory``, a full disk says so.  Python warnings that libraries (numpy, trimesh, ...) raise
during a command are held back (:func:`held_warnings`): a failed command prints only its error
line; a successful one prints each distinct warning once at the end, as one line
``envcap: note: a library warned: ...``.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import os
import pkgutil
import sys
import warnings
from collections.abc import Iterator

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


def error_text(exc: BaseException) -> str:
    """The one line that ``envcap: error:`` prints for a user error ``exc``."""
    if isinstance(exc, KeyError):
        return f"missing key {exc}"
    text = str(exc)
    if isinstance(exc, OSError) and exc.errno is not None and exc.strerror and text.startswith("[Errno"):
        where = " -> ".join(str(f) for f in (exc.filename, exc.filename2) if f)
        reason = exc.strerror[:1].lower() + exc.strerror[1:]
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            reason += " (the disk is full)" if exc.errno == errno.ENOSPC else " (the disk quota is used up)"
        text = f"{where}: {reason}" if where else reason
    return " ".join(text.split()) or type(exc).__name__


@contextlib.contextmanager
def held_warnings() -> Iterator[list[warnings.WarningMessage]]:
    """Record the Python warnings raised inside the block instead of printing them (see the module
    docstring); the filters stay as they are, so what would have been printed is what is held."""
    with warnings.catch_warnings(record=True) as caught:
        yield caught


def print_held_warnings(caught: list[warnings.WarningMessage]) -> None:
    """Each distinct held warning once, as one line on stderr."""
    for category, message in dict.fromkeys((w.category.__name__, " ".join(str(w.message).split())) for w in caught):
        print(f"envcap: note: a library warned: {category}: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        with sigterm_raises(), held_warnings() as caught:
            code = int(args.func(args) or 0)
        print_held_warnings(caught)
        return code
    except KeyboardInterrupt:
        print("envcap: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Terminated:
        print("envcap: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except USER_ERRORS as exc:
        print(f"envcap: error: {error_text(exc)}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
