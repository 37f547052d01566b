"""The opt-in ``sky_visibility`` writer: a probe set written with it holds the packed visibility
moments of its captures (read back through the KTX2 reader and against the filter run here) and
their table; the default writers and today's manifests are unchanged."""

import dataclasses
import json

import numpy as np

from envcap.core.rungs import rung_ladder
from envcap.formats import sky_visibility_writer
from envcap.formats.ktx2 import read_ktx2
from envcap.formats.registry import WRITERS, default_writer_names
from envcap.prefilter.sky_visibility import prefilter_sky_visibility, project_sh
from envcap.probeset.store import write_probe_set
from envcap.runtime.sky_visibility import GRADIENT_STEP


def test_sky_visibility_writer_round_trip(canyon_probe_set, gl_ctx, tmp_path):
    assert "sky_visibility" in WRITERS and "sky_visibility" not in default_writer_names()
    assert sky_visibility_writer.GRADIENT_STEP == GRADIENT_STEP
    out = write_probe_set(tmp_path / "ps", canyon_probe_set, exr=False, previews=False,
                          writers=["ktx2", "sky_visibility"])
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["files"]["sky_visibility"] == "sky_visibility.ktx2"
    table = json.loads((out / manifest["files"]["sky_visibility_table"]).read_text())
    lad = rung_ladder(8, "half_octave")           # a paper set at 8^2: the half-octave ladder, one level
    assert table["order"] == 1 and table["first_level"] == 0 and table["ladder"] == lad.to_manifest()
    want = prefilter_sky_visibility(np.asarray(canyon_probe_set.levels[0])[..., 3], lad, 1, ctx=gl_ctx)
    levels, info = read_ktx2(out / "sky_visibility.ktx2")
    assert info["fmt"] == "rgba16f" and table["layers_per_probe"] == want.layers_per_probe == 4
    assert len(levels) == 1 and levels[0].shape == (canyon_probe_set.layer_count * 4, 6, 8, 8, 4)
    np.testing.assert_allclose(levels[0], want.packed_levels()[0], atol=1e-3)
    np.testing.assert_allclose(table["baked_sky_sh"],
                               project_sh(np.asarray(canyon_probe_set.sky_levels[0], np.float64)[..., :3], 1), rtol=1e-12)
    plain = write_probe_set(tmp_path / "plain", canyon_probe_set, exr=False, previews=False, writers=["ktx2"])
    assert "sky_visibility" not in json.loads((plain / "manifest.json").read_text())["files"]
    assert not (plain / "sky_visibility.ktx2").exists()
    assert "probe_yaw_deg" not in table and "frame" not in table      # unframed: today's table


def test_sky_visibility_writer_records_street_frames(canyon_probe_set, tmp_path):
    # the moments are the captures' (already in each street's frame); the table says which frame
    ps = canyon_probe_set
    st = ps.manifest.streets[0]
    framed = dataclasses.replace(ps, manifest=dataclasses.replace(
        ps.manifest, streets=(dataclasses.replace(st, yaw_deg=30.0), *ps.manifest.streets[1:])))
    files = sky_visibility_writer.write_sky_visibility(tmp_path, framed)
    table = json.loads((tmp_path / files["sky_visibility_table"]).read_text())
    want = [0.0] * ps.layer_count
    for p in st.probes:
        want[p.layer] = 30.0
    assert table["probe_yaw_deg"] == want and "frame" in table
