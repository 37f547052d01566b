"""The dynamic-street benchmark's crowd positions on a street at an angle are offset along and
across that street, not along the world's axes (review of issue 10)."""

import json
import math
from pathlib import Path

import numpy as np

from envcap.benchmarks.dynamic_street import HEIGHT_M, crowd_positions
from envcap.probeset.manifest import Manifest

V1_FILE = Path(__file__).resolve().parents[1] / "probeset/data/manifest_v1_canyon.json"
YAW, ORIGIN = 37.0, (10.0, 23.5)


def _manifest(framed: bool) -> Manifest:
    raw = json.loads(V1_FILE.read_text())
    if framed:      # the probes on the frame's x axis, turned by hand: x_w = o + s u, u = (cos, sin) of the yaw
        st = raw["streets"][0]
        st["yaw_deg"], st["origin_xz"] = YAW, list(ORIGIN)
        u = (math.cos(math.radians(YAW)), math.sin(math.radians(YAW)))
        for i, pr in enumerate(st["probes"]):
            s = 5.0 + 10.0 * i
            pr["position"] = [ORIGIN[0] + s * u[0], 2.0, ORIGIN[1] + s * u[1]]
    return Manifest.from_json(raw)


def test_crowd_offsets_follow_the_street():
    offsets = ((0.0, 0.0), (0.5, 3.0), (0.25, -4.0), (0.75, -2.0), (0.5, 0.0), (0.1, 5.0))
    for framed in (False, True):
        m = _manifest(framed)
        st = m.streets[0]
        a = math.radians(YAW if framed else 0.0)
        u, v = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])   # along, across (+z_f)
        probe = np.array(st.probes[len(st.probes) // 2].position)
        got = np.array(crowd_positions(m, 6, 20.0))
        want = [probe[[0, 2]] + fa * 20.0 * u + dc * v for fa, dc in offsets]
        np.testing.assert_allclose(got[:, [0, 2]], want, atol=1e-9)
        assert np.all(got[:, 1] == HEIGHT_M)
