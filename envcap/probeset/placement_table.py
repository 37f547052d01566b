"""The manifest's optional ``placement`` entry: how the probes of a set were placed along its
streets (``envcap capture --placement NAME --probes-per-street N``; ``docs/placement.md``).

A set without the entry (JSON key absent: every set baked before it existed, and every bake at
the default placement) has its probes at a uniform ``probe_spacing`` along each street, centred
(:func:`envcap.probeset.placement.place_probes`).  With it, ``strategy`` names the placement
strategy (:mod:`envcap.placement`), ``probes_per_street`` the count asked for every street
(``None``: each street's count followed from ``probe_spacing`` and its length), ``parameters``
the strategy's parameters (free-form JSON), ``seconds`` what placing cost (wall time, the
strategy's own pre-captures and evaluator passes included) and ``streets`` what the strategy
recorded about its choice per street name (free-form JSON, e.g. its training error beside
uniform's).  The probes' positions themselves are the streets' ``probes``; ``probe_spacing`` is
then the mean spacing (the streets' length over their probes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from envcap.probeset.json_codec import ManifestError

__all__ = ["PlacementTable", "check_placement_table"]


@dataclass(frozen=True)
class PlacementTable:
    """How the probes were placed (module docstring): strategy name, the count per street
    (``None``: from the spacing), its parameters, the seconds it took and per-street notes."""

    strategy: str
    probes_per_street: int | None = field(default=None, metadata={"json": "omit_none"})
    parameters: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    streets: dict[str, Any] = field(default_factory=dict)


def check_placement_table(t: PlacementTable, street_names: list[str], where: str) -> None:
    """``ManifestError`` (one line naming ``where``) unless ``t`` names a strategy, a count >= 1
    (or none), a finite time >= 0 and notes only for streets of the set."""
    if not t.strategy or not t.strategy.isidentifier():
        raise ManifestError(f"{where}: placement.strategy must be a strategy name (an identifier), got {t.strategy!r}")
    if t.probes_per_street is not None and t.probes_per_street < 1:
        raise ManifestError(f"{where}: placement.probes_per_street must be >= 1, got {t.probes_per_street}")
    if not (math.isfinite(t.seconds) and t.seconds >= 0):
        raise ManifestError(f"{where}: placement.seconds must be a finite number >= 0, got {t.seconds!r}")
    unknown = sorted(set(t.streets) - set(street_names))
    if unknown:
        raise ManifestError(f"{where}: placement.streets names streets the set does not have: {unknown}")
