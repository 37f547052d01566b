"""Streets at any angle in the manifest (issue 10): ``yaw_deg``/``origin_xz`` and ``ground_slope``
round-trip, validate against the published schema, and are absent (today's bytes) when unset."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import jsonschema
import pytest

from envcap.core.street_frame import frame_to_world
from envcap.probeset.manifest import Manifest, manifest_text

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = json.loads((ROOT / "docs/manifest.schema.json").read_text())
V1_FILE = Path(__file__).parent / "data/manifest_v1_canyon.json"


def _framed(raw: dict, yaw: float = 37.0, origin=(10.0, 23.5)) -> dict:
    """``raw`` with its street framed: the probes' world positions on the frame's x axis."""
    out = copy.deepcopy(raw)
    st = out["streets"][0]
    st["yaw_deg"], st["origin_xz"] = yaw, list(origin)
    for i, pr in enumerate(st["probes"]):
        pr["position"] = [float(v) for v in frame_to_world([5.0 + 10.0 * (1 - i), 2.0, 0.0], yaw, origin)]
        pr["planes"]["ground_slope"] = 0.04
        if pr["fitted_planes"] is not None:
            pr["fitted_planes"]["ground_slope"] = -0.01
    return out


def test_framed_streets_and_slopes_round_trip_and_validate():
    raw = _framed(json.loads(V1_FILE.read_text()))
    jsonschema.validate(raw, SCHEMA)
    m = Manifest.from_json(raw)
    st = m.streets[0]
    assert (st.yaw_deg, st.origin_xz, st.frame_yaw_deg, st.frame_origin_xz, st.framed) == \
        (37.0, (10.0, 23.5), 37.0, (10.0, 23.5), True)
    assert st.probes[0].planes.ground_slope == 0.04 and st.probes[0].planes.slope == 0.04
    # probes_along sorts by the FRAME x (probe 1 at x_f = 5, probe 0 at x_f = 15).
    assert [p.index for p in st.probes_along()] == [st.probes[1].index, st.probes[0].index]
    text = manifest_text(m)
    assert json.loads(text) == raw and manifest_text(Manifest.from_json(json.loads(text))) == text
    fitted = [p.fitted_planes for p in st.probes if p.fitted_planes is not None]
    assert fitted and all(f.ground_slope == -0.01 and f.merged(st.planes).ground_slope == -0.01 for f in fitted)


def test_unset_frame_and_slope_keep_todays_keys():
    raw = json.loads(V1_FILE.read_text())
    m = Manifest.from_json(raw)
    st = m.streets[0]
    assert st.yaw_deg is None and st.frame_yaw_deg == 0.0 and st.frame_origin_xz == (0.0, 0.0) and not st.framed
    assert st.planes.ground_slope is None and st.planes.slope == 0.0
    assert manifest_text(m) == V1_FILE.read_text()


@pytest.mark.parametrize("mutate,msg", [
    (lambda s: s.update(axis="z"), r"streets\[0\].axis: a street with yaw_deg/origin_xz"),
    (lambda s: s.update(origin_xz=[1.0]), r"streets\[0\].origin_xz: must be an array of 2 entries"),
    (lambda s: s.update(yaw_deg="north"), r"streets\[0\].yaw_deg: must be a finite number"),
    (lambda s: s["planes"].update(ground_slope="steep"), r"streets\[0\].planes.ground_slope: must be a finite number"),
])
def test_framed_street_errors_name_the_field(mutate, msg):
    raw = _framed(json.loads(V1_FILE.read_text()))
    mutate(raw["streets"][0])
    with pytest.raises(ValueError, match=msg):
        Manifest.from_json(raw, "manifest.json")
    if "axis" not in msg:
        assert not jsonschema.Draft202012Validator(SCHEMA).is_valid(raw)
