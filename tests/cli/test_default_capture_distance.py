"""``envcap evaluate`` on a default ``envcap capture`` runs every method: the default bake writes
``inverse_distance.ktx2``, and reading the set back gives its distance channel from it (it used to
warn "no distance channel" and skip the depth-aware methods unless ``--exr`` was given)."""

import json

import numpy as np
from envcap_process import run_envcap

from envcap.probeset.store import read_probe_set
from envcap.runtime.methods import BUILTIN

SMALL = ("--resolution", "16", "--spacing", "20", "--quiet")


def test_default_capture_then_evaluate_runs_every_method(tmp_path):
    r = run_envcap("capture", "planes", "--out", "P", *SMALL, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "P" / "inverse_distance.ktx2").is_file() and not (tmp_path / "P" / "exr").exists()
    r = run_envcap("evaluate", "planes", "--probes", "P", "--out", "E", "--positions", "2", "--resolution", "8",
                   "--lobes", "64", "--no-images", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "distance" not in r.stderr and "skipping" not in r.stderr, r.stderr
    text = (tmp_path / "E" / "report.md").read_text() + json.dumps(json.loads((tmp_path / "E" / "report.json").read_text()))
    for m in BUILTIN:
        assert m.name in text, m.name
    assert any(m.needs_distance for m in BUILTIN)


def test_distance_from_the_inverse_texture_is_the_exr_distance_within_half_float_rounding(tmp_path):
    """The independent reference: the same bake's float32 EXR Z channel."""
    r = run_envcap("capture", "planes", "--out", "PE", *SMALL, "--exr", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    with_exr = read_probe_set(tmp_path / "PE").distance
    doc = json.loads((tmp_path / "PE" / "manifest.json").read_text())
    doc["files"].pop("exr")                       # the same set, read as if it had no EXR files
    only_inv = tmp_path / "PI"
    only_inv.mkdir()
    for name in ("probes.ktx2", "sky.ktx2", "inverse_distance.ktx2"):
        (only_inv / name).write_bytes((tmp_path / "PE" / name).read_bytes())
    (only_inv / "manifest.json").write_text(json.dumps(doc))
    got = read_probe_set(only_inv).distance
    assert got is not None and got.shape == with_exr.shape and got.dtype == np.float32
    assert np.array_equal(got > 0, with_exr > 0)                      # the sky is 0 in both
    rel = np.abs(got - with_exr)[with_exr > 0] / with_exr[with_exr > 0]
    assert rel.max() <= 2.0 ** -11 * 1.001


def test_no_inverse_distance_skips_it(tmp_path):
    r = run_envcap("capture", "planes", "--out", "P", *SMALL, "--no-inverse-distance", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "P" / "inverse_distance.ktx2").exists()
    assert read_probe_set(tmp_path / "P").distance is None
