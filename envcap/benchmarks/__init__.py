"""Benchmarks, run as ``envcap bench NAME``: one module per benchmark in this package.

Each module defines ``add_arguments(parser)`` and ``run(args) -> int``, and writes its results
(JSON + plots) where ``--out`` says, so that every figure in ``docs/`` can be reproduced with one
command.  Times are reported as ratios to the simplest correct method measured in the same run.
"""
