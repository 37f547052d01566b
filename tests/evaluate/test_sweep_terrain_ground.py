"""The evaluator's sweep on a street that follows the terrain: positions stand above each probe's
own ground, also where that ground is flat (slope 0) but not the street's nominal one (review of
issue 10: a flat street on a plateau 50 m up was swept 50 m below its probes)."""

import json
from pathlib import Path

import numpy as np
import pytest

from envcap.evaluate.sweep import StreetExtent, Sweep, sample_positions
from envcap.probeset.manifest import Manifest

V1_FILE = Path(__file__).resolve().parents[1] / "probeset/data/manifest_v1_canyon.json"


def _terrain_manifest(grounds, slopes) -> Manifest:
    """The v1 canyon manifest with its probes standing 2 m above ``grounds`` of ``slopes``."""
    raw = json.loads(V1_FILE.read_text())
    for pr, g, k in zip(raw["streets"][0]["probes"], grounds, slopes):
        pr["planes"]["ground"], pr["planes"]["ground_slope"] = g, k
        pr["position"][1] = g + 2.0
    return Manifest.from_json(raw)


@pytest.mark.parametrize("grounds,slopes", [((50.0, 50.0), (0.0, 0.0)),      # a plateau: flat, 50 m up
                                            ((10.0, 12.5), (0.0, 0.0)),      # steps, each probe flat
                                            ((10.0, 12.5), (0.5, 0.25))])    # different grounds and slopes
def test_sweep_heights_are_above_each_probes_ground(grounds, slopes):
    m = _terrain_manifest(grounds, slopes)
    ext = StreetExtent.from_manifest(m.streets[0])
    probes = m.streets[0].probes_along()
    sweep = Sweep(per_street=12)
    for ep in sample_positions(m, sweep):
        s = ep.position[ext.along]
        i = int(np.argmin([abs(p.position[ext.along] - s) for p in probes]))   # the nearest probe (hand)
        pl, ps = probes[i].planes, probes[i].position[ext.along]
        under = pl.ground + pl.slope * (s - ps)
        assert ep.position[1] - under == pytest.approx(ep.height, abs=1e-9)
        assert sweep.heights[0] <= ep.height <= sweep.heights[1]


def test_a_street_on_its_nominal_ground_keeps_todays_positions():
    m = Manifest.from_json(json.loads(V1_FILE.read_text()))
    flat = _terrain_manifest((0.0, 0.0), (0.0, 0.0))      # the same grounds, slopes written as 0
    assert [ep.position for ep in sample_positions(m)] == [ep.position for ep in sample_positions(flat)]
