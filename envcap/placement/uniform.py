"""``uniform``: the probes at a uniform spacing, centred on the street (the default).

``count`` probes stand ``length / count`` apart, the end probes half a spacing from the street's
ends: exactly :func:`envcap.probeset.placement.place_probes` at spacing ``length / count`` (and at
the CLI's ``--spacing``, whose count is ``floor(length / spacing)``, its positions bit for bit).
Needs: nothing (no capture).  Parameters: ``spacing_m`` (``None``: ``length / count``; given: the
probes stand that far apart, centred, as ``place_probes`` puts them).
"""

from __future__ import annotations

from collections.abc import Sequence

from envcap.placement.registry import PlacementContext, PlacementStrategy, StreetPlacement
from envcap.probeset.placement import uniform_along
from envcap.scene.model import Street


def place(context: PlacementContext, street: Street, counts: Sequence[int],
          spacing_m: float | None = None) -> list[StreetPlacement]:
    """``count`` probes ``spacing_m`` (default ``length / count``) apart, centred on the street."""
    return [StreetPlacement(uniform_along(street, n, spacing_m)) for n in counts]


STRATEGY = PlacementStrategy("uniform", place, "a uniform spacing, centred on the street (the default)",
                             parameters={"spacing_m": None})
