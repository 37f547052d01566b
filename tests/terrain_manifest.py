"""A probe-set manifest of a street that follows the terrain, for tests of where things stand on it
(review of issue 10): the v1 canyon manifest (street ``main`` along frame x, probes at along
coordinates -297.5 and -292.5 m) with each probe's ground and slope set, its probe 2 m above its
ground, optionally turned in plan (``yaw_deg`` about +Y at :data:`ORIGIN`)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from envcap.probeset.manifest import Manifest

V1_FILE = Path(__file__).resolve().parent / "probeset/data/manifest_v1_canyon.json"
PROBE_S = (-297.5, -292.5)
"""Along coordinates (m, the street's frame) of the two probes."""
ORIGIN = (10.0, 23.5)
"""Plan origin (x, z) m of the turned street's frame."""


def along_unit(yaw_deg: float) -> np.ndarray:
    """The street's along axis in plan, (x, z), for a street turned by ``yaw_deg`` (frame +x)."""
    a = math.radians(yaw_deg)
    return np.array([math.cos(a), math.sin(a)])


def terrain_manifest(grounds: tuple[float, float], slopes: tuple[float, float], yaw_deg: float = 0.0) -> Manifest:
    """The v1 canyon manifest with probe ``i`` standing 2 m above ``grounds[i]`` (m), its ground
    rising ``slopes[i]`` m per m along the street; turned by ``yaw_deg`` when not 0."""
    raw = json.loads(V1_FILE.read_text())
    st = raw["streets"][0]
    o = np.array(ORIGIN) if yaw_deg else np.zeros(2)
    if yaw_deg:
        st["yaw_deg"], st["origin_xz"] = yaw_deg, list(ORIGIN)
    for pr, s, g, k in zip(st["probes"], PROBE_S, grounds, slopes):
        xz = o + s * along_unit(yaw_deg)
        pr["planes"]["ground"], pr["planes"]["ground_slope"] = g, k
        pr["position"] = [float(xz[0]), g + 2.0, float(xz[1])]
    return Manifest.from_json(raw)


def hand_ground(x: np.ndarray, grounds: tuple[float, float], slopes: tuple[float, float], yaw_deg: float = 0.0) -> float:
    """Ground height (m) under the world point ``x`` (3,): the nearest probe's ground plane along the
    street, ``g_i + k_i (s - s_i)`` at ``x``'s along coordinate ``s`` (the plan projection on the
    street's axis), by hand."""
    o = np.array(ORIGIN) if yaw_deg else np.zeros(2)
    s = float((np.asarray(x, np.float64)[[0, 2]] - o) @ along_unit(yaw_deg))
    i = int(np.argmin([abs(s - p) for p in PROBE_S]))
    return grounds[i] + slopes[i] * (s - PROBE_S[i])
