"""Probe placement strategies, one file each, and their registry (docs/placement.md).

Every strategy file defines ``STRATEGY``, a :class:`PlacementStrategy` (name, the function that
places a street's probes, its parameters), documented in its module docstring.  A new strategy is
one file here plus one entry in the ``BUILTIN`` line below (or a :func:`register` call from
outside the package); ``envcap capture --placement NAME`` (:func:`envcap.placement.place.place_scene`)
and ``envcap bench placement`` find it by name.
"""

from __future__ import annotations

from envcap.placement import density, min_error, uniform
from envcap.placement.registry import (PlacementContext, PlacementStrategy, StreetPlacement, get, register, registered,
                                       unregister)

BUILTIN: tuple[PlacementStrategy, ...] = (uniform.STRATEGY, density.STRATEGY, min_error.STRATEGY)
"""The built-in strategies, the default (``uniform``) first."""

for _strategy in BUILTIN:
    register(_strategy)

STRATEGIES: tuple[str, ...] = tuple(s.name for s in BUILTIN)
"""Names of the built-in strategies."""

__all__ = ["BUILTIN", "STRATEGIES", "PlacementContext", "PlacementStrategy", "StreetPlacement", "get", "register",
           "registered", "unregister"]
