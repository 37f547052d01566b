"""Probe placement along a street's center line.

A street (:class:`envcap.scene.model.Street`) has a probe line along its center at a fixed
height.  Each probe records its nominal planes (:class:`envcap.probeset.planes.Planes`, from the
street description); the bake fits its own planes from its capture
(:func:`envcap.probeset.planes.fit_planes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from envcap.probeset.planes import Planes
from envcap.scene.model import Street


@dataclass(frozen=True)
class ProbePlacement:
    """One probe: its street, index along the street, world position (m) and nominal planes."""

    street: str
    index: int
    position: tuple[float, float, float]
    planes: Planes


def place_probes(street: Street, spacing: float = 5.0, height: float = 2.0) -> list[ProbePlacement]:
    """Probes along ``street``'s center line at ``height`` m above its ground, ``spacing`` m apart.

    The probes are spaced exactly ``spacing`` apart and centered on the street: there are
    ``max(1, floor(length / spacing))`` of them, so that each stands at least ``spacing / 2``
    from the street's ends (a street shorter than ``spacing`` gets one probe at its middle).
    The height must lie strictly between the ground and 1 km; the spacing must be positive.
    """
    if not (isinstance(spacing, (int, float)) and math.isfinite(spacing) and spacing > 0):
        raise ValueError(f"probe spacing must be a positive number of meters, got {spacing!r}")
    if not (isinstance(height, (int, float)) and math.isfinite(height) and 0 < height < 1000):
        raise ValueError(f"probe height must be in (0, 1000) m above the ground, got {height!r}")
    count = max(1, int(math.floor(street.length / spacing + 1e-9)))
    mid = 0.5 * (street.start + street.end)
    planes = Planes(street.facade_min, street.facade_max, street.ground)
    out = []
    for i in range(count):
        along = mid + (i - 0.5 * (count - 1)) * spacing
        pos = [0.0, street.ground + height, 0.0]
        pos[street.along_index] = along
        pos[street.cross_index] = street.center_line
        out.append(ProbePlacement(street.name, i, (pos[0], pos[1], pos[2]), planes))
    return out
