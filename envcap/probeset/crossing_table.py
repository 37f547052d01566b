"""The manifest's optional ``crossings`` table: where streets of the set meet and which probe
stands at each crossing's centre (``docs/crossings.md``; the geometry: :mod:`envcap.probeset.crossings`).

Each entry: ``name`` (unique within the set, e.g. ``"east_west+north_south"``), ``centre`` (x, y, z)
m, the crossing probe's world position (plan: where the streets' centre lines meet; height: the
probe's), ``streets`` the names of the meeting streets (>= 2, streets of the set, each once) and
``probe_layer`` the layer of the probe at the centre: a probe of the first meeting street (its
probe line passes through the centre), shared by all of them.  A set without the entry (JSON key
absent: sets baked before it existed, and bakes with ``--no-crossings``) has no crossings; its
lookups stay per street.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from envcap.probeset.json_codec import ManifestError

__all__ = ["Crossing", "check_crossing_table"]


@dataclass(frozen=True)
class Crossing:
    """One crossing (module docstring): its name, centre (m), meeting streets and probe layer."""

    name: str
    centre: tuple[float, float, float]
    streets: tuple[str, ...]
    probe_layer: int


def check_crossing_table(crossings: Sequence[Crossing], street_layers: dict[str, list[int]], where: str) -> None:
    """``ManifestError`` (one line naming ``where``) unless every crossing has a unique name, a
    finite centre, >= 2 distinct streets of the set and a probe layer of its first street."""
    names: set[str] = set()
    for k, c in enumerate(crossings):
        cw = f"{where}: crossings[{k}]"
        if not c.name or c.name in names:
            raise ManifestError(f"{cw}.name: must be a non-empty name, unique in the set, got {c.name!r}")
        names.add(c.name)
        if not all(math.isfinite(v) for v in c.centre):
            raise ManifestError(f"{cw}.centre: must be finite, got {c.centre}")
        if len(c.streets) < 2 or len(set(c.streets)) != len(c.streets):
            raise ManifestError(f"{cw}.streets: a crossing needs at least two distinct streets, got {list(c.streets)}")
        unknown = [s for s in c.streets if s not in street_layers]
        if unknown:
            raise ManifestError(f"{cw}.streets: names streets the set does not have: {unknown}")
        if c.probe_layer not in street_layers[c.streets[0]]:
            raise ManifestError(f"{cw}.probe_layer: {c.probe_layer} is not a probe of its first street {c.streets[0]!r}")
