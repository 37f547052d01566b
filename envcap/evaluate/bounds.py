"""Bounds before work for an evaluation: position count, truth face size, peak memory, rough time.

:func:`envcap.evaluate.run.evaluate_scene` (and ``envcap evaluate``, before it reads or bakes a
probe set) calls :func:`check_evaluation` before it builds the sky or captures anything, so that a
request that would run away with the machine (``--positions 100000000``: a Python object per
position, days of captures; ``--resolution 99999999999999999999``: numpy's "Maximum allowed size
exceeded") fails at once with one line saying what was asked, what it would cost and which option
changes it (:class:`envcap.core.budget.BudgetError`).

The cost model (:func:`estimate_evaluation`) was measured with llvmpipe (Mesa's CPU OpenGL,
2 cores): ``envcap evaluate planes --bake 10 --probe-resolution 32 --positions 4 --resolution 64``
(6 methods, 7 lobe powers, both sun variants: 4 + 2 floor + 3 image-strip positions) ran 32 s
at a peak of 313 MB resident, most of it the process itself.  Memory is checked against
:func:`envcap.core.budget.memory_limit`, the count against :data:`MAX_POSITIONS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from envcap.core.budget import check_bytes, check_count, format_bytes
from envcap.probeset.bake_bounds import format_seconds

__all__ = ["MAX_POSITIONS", "EvaluationEstimate", "estimate_evaluation", "check_evaluation"]

MAX_POSITIONS = 10_000
"""Most evaluation positions of one evaluation (all streets; ~10 h at 64^2 at llvmpipe rates).
Raise it with ``evaluate_scene(..., max_positions=N)``."""

# Peak bytes per truth texel (6 N^2): the sky cubes (RGB and RGBA, with and without the sun) and
# their filtered copies, the capture (RGBA + distance), the float64 copies of the truth filter and
# the predictions at the mirror grid (directions, street RGBA per method); fitted generously.
_TEXEL_B = 400.0
_ROW_B = 2048.0         # one result row (a dict of ~14 entries) per position, power, method, sun variant
_BASE_B = 64 << 20      # a GL context and the capture target
# Seconds at llvmpipe rates per truth texel of one position (capture, filtering at 7 powers,
# predictions of 6 methods, shading), for each evaluated position.
_TEXEL_S = 1.4e-4 / 42.0  # per texel, per (lobe power x method)
_EXTRA_POSITIONS = 5      # the floor (2 probe positions) and the image strips (3 worst positions)


@dataclass(frozen=True)
class EvaluationEstimate:
    """What an evaluation will hold and take, before it starts.

    ``positions``: evaluated positions (a float: may be huge); ``resolution``: truth face size N;
    ``peak_bytes``: peak memory added by the evaluation; ``seconds``: rough wall time at llvmpipe
    rates (a GPU is faster).
    """

    positions: float
    resolution: int
    peak_bytes: float
    seconds: float

    def describe(self, memory: bool = True) -> str:
        """``"16 positions at 64^2 per face: peak memory ~64.1 MiB, roughly 56 s at llvmpipe (CPU) rates"``
        (without the memory part if not ``memory``)."""
        count = f"{int(self.positions):,}" if self.positions < 1e15 else f"{self.positions:.3g}"
        n = self.resolution
        size = str(n) if n < 10 ** 15 else f"{float(n):.3g}" if n < 1 << 1000 else "1e301+"
        mem = f"peak memory ~{format_bytes(self.peak_bytes)}, " if memory else ""
        return (f"{count} position(s) at {size}^2 per face: {mem}"
                f"roughly {format_seconds(self.seconds)} at llvmpipe (CPU) rates")


def estimate_evaluation(positions: float, resolution: int, lobe_powers: int = 7, methods: int = 6,
                        sun_variants: int = 2) -> EvaluationEstimate:
    """The cost model of evaluating ``positions`` positions with truth captures of ``resolution``
    texels per face, ``lobe_powers`` powers, ``methods`` methods and ``sun_variants`` sky variants
    (see the module docstring); every quantity is a float (``inf`` when past counting)."""
    n = float(resolution) if resolution < 1 << 1000 else math.inf
    texels = 6.0 * n * n
    combos = max(lobe_powers, 1) * max(methods, 1)
    rows = float(positions) * combos * max(sun_variants, 1)
    peak = _TEXEL_B * texels + _ROW_B * rows + _BASE_B
    seconds = (float(positions) + _EXTRA_POSITIONS) * texels * _TEXEL_S * combos
    return EvaluationEstimate(float(positions), int(resolution), peak, seconds)


def check_evaluation(est: EvaluationEstimate, *, max_positions: int = MAX_POSITIONS,
                     positions_option: str = "--positions", resolution_option: str = "--resolution") -> None:
    """Refuse ``est`` past ``max_positions`` positions or past the memory limit
    (:class:`envcap.core.budget.BudgetError`: what was asked, its cost and the option to change)."""
    check_count(f"evaluation positions ({est.describe()})", est.positions, max_positions,
                f"{positions_option} (or max_positions= of evaluate_scene)")
    check_bytes(f"evaluation of {est.describe(memory=False)}", est.peak_bytes, f"{resolution_option} or {positions_option}")
