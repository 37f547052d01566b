"""Subcommands of the ``envcap`` CLI: each module defines ``register(subparsers)``.

``register`` adds one (or more) subparsers and sets ``func=handler`` on them; a handler takes
the parsed ``argparse.Namespace`` and returns an exit code.
"""
