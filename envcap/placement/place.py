"""Place the probes of every street of a scene with a strategy: what ``envcap capture --placement``
runs before the bake.

:func:`place_scene` resolves the count of each street (``probes_per_street``, or from ``spacing``
and the street's length as :func:`envcap.probeset.placement.probe_count` says), refuses a count
past the bake's limit before any work (one line with the bake's estimate, naming
``--probes-per-street``), runs the strategy street by street (one GL context for all when it
captures) and returns the along-street coordinates per street with the manifest's ``placement``
table (:class:`envcap.probeset.placement_table.PlacementTable`), ready for
:func:`envcap.probeset.bake.bake_probe_set` (``along=``, ``placement=``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.budget import check_count
from envcap.gpu.context import create_context
from envcap.placement.registry import PlacementContext, PlacementStrategy, get
from envcap.probeset.bake_bounds import estimate_bake
from envcap.probeset.placement import MAX_PROBES, check_height, probe_count
from envcap.probeset.placement_table import PlacementTable
from envcap.scene.model import Scene


@dataclass(frozen=True)
class ScenePlacement:
    """The probes' along-street coordinates (m, each street's frame) per street name, and the
    manifest's record of how they were placed."""

    along: dict[str, NDArray[np.float64]]
    table: PlacementTable


def check_probes_per_street(value: Any) -> int:
    """``value`` as a probe count per street: a whole number >= 1 (an int, or a string of digits
    as typed; ``ValueError`` naming ``--probes-per-street``)."""
    text = value.strip() if isinstance(value, str) else value
    if isinstance(text, str) and text.isdigit():
        text = int(text)
    if isinstance(text, bool) or not isinstance(text, (int, np.integer)) or text < 1:
        raise ValueError(f"--probes-per-street must be a whole number of probes >= 1, got {value!r}")
    return int(text)


def street_counts(scene: Scene, probes_per_street: int | None, spacing: float) -> list[float]:
    """The probe count of each street: ``probes_per_street`` on every one, else from ``spacing``
    (m) and its length (floats: a count past counting stays ``inf`` until it is refused)."""
    if probes_per_street is not None:
        return [float(check_probes_per_street(probes_per_street))] * len(scene.streets)
    return [probe_count(st, spacing) for st in scene.streets]


def plain_json(value: Any) -> Any:
    """``value`` as plain JSON data (tuples and numpy arrays as lists, numpy scalars as Python's)."""
    if isinstance(value, Mapping):
        return {str(k): plain_json(v) for k, v in value.items()}
    if isinstance(value, (tuple, list, np.ndarray)):
        return [plain_json(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def place_scene(scene: Scene, strategy: str | PlacementStrategy = "uniform", *, probes_per_street: int | None = None,
                spacing: float = 5.0, height: float = 2.0, resolution: int = 64, parameters: Mapping[str, Any] | None = None,
                ctx: Any = None, max_probes: int = MAX_PROBES, verbose: bool = False) -> ScenePlacement:
    """Place the probes of every street of ``scene`` with ``strategy`` (a registered name).

    ``probes_per_street``: the count on every street (``None``: from ``spacing`` m and each
    street's length; ``uniform`` then puts them exactly where ``place_probes`` does).  ``height``
    (m above the ground) and ``resolution`` (the bake's face size) are the bake's: strategies that
    pre-capture use them.  ``parameters``: the strategy's, overriding its defaults (recorded).
    ``ctx``: a moderngl context (made for a strategy that captures when ``None``).  More than
    ``max_probes`` probes in all are refused before any work (``BudgetError``: the count asked, the
    bake's estimate, the option to change).
    """
    strat = get(strategy)
    settings = strat.settings(parameters)
    if not scene.streets:
        raise ValueError(f"scene '{scene.name}' has no streets: nothing to place probes along")
    check_height(height)
    counts = street_counts(scene, probes_per_street, spacing)
    total = sum(counts)
    option = "--probes-per-street" if probes_per_street is not None else "--spacing"
    est = estimate_bake(total, resolution, quality="composed")
    asked = (f"{probes_per_street} probes per street on {len(scene.streets)} street(s)" if probes_per_street is not None
             else f"probes for {sum(st.length for st in scene.streets):g} m of streets at spacing {spacing:g} m")
    check_count(f"{asked} (a bake of ~{est.describe()})", total if math.isfinite(total) else math.inf, max_probes, option)
    if strat.name == "uniform" and probes_per_street is None and "spacing_m" not in (parameters or {}):
        settings["spacing_m"] = float(spacing)          # the --spacing placement itself, bit for bit
    own = strat.needs_gl and ctx is None
    gl = create_context() if own else ctx
    t0 = time.perf_counter()
    along: dict[str, NDArray[np.float64]] = {}
    notes: dict[str, Any] = {}
    try:
        context = PlacementContext(scene, float(height), int(resolution), gl, verbose)
        for st, n in zip(scene.streets, counts):
            placed = strat(context, st, (int(n),), **settings)[0]
            along[st.name] = placed.along
            if placed.notes:
                notes[st.name] = plain_json(placed.notes)
            if verbose:
                print(f"{scene.name}: street '{st.name}': {int(n)} probes placed by {strat.name} "
                      f"({time.perf_counter() - t0:.1f} s)", flush=True)
    finally:
        if own:
            gl.release()
    table = PlacementTable(strat.name, None if probes_per_street is None else int(probes_per_street),
                           plain_json(settings), round(time.perf_counter() - t0, 3), notes)
    return ScenePlacement(along, table)
