"""Cutting a scene's streets to a segment (for short probe sets: tests, benchmarks, ``envcap evaluate --bake``)."""

from __future__ import annotations

import dataclasses
import math

from envcap.core.checks import format_number
from envcap.scene.model import Scene


def street_segment(scene: Scene, length: float, center: float | None = None) -> Scene:
    """A copy of ``scene`` whose streets are cut to ``length`` m around ``center`` (m along each
    street; default: each street's middle), for baking a short probe set; the geometry is unchanged."""
    if not (math.isfinite(length) and length > 0):
        raise ValueError(f"segment length (evaluate --bake) must be a positive number of meters, got {format_number(length)}")
    streets = []
    for st in scene.streets:
        c = 0.5 * (st.start + st.end) if center is None else float(center)
        a, b = max(st.start, c - 0.5 * length), min(st.end, c + 0.5 * length)
        if not b > a:
            raise ValueError(f"street {st.name!r} ({st.start}..{st.end}) has no part within {length} m of {c}")
        streets.append(dataclasses.replace(st, start=a, end=b))
    return dataclasses.replace(scene, streets=streets)
