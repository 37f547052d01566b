"""`envcap capture --webgl2 --latlong`: the opt-in engine outputs (docs/engines.md) land in the probe
set and its manifest; they are opt-in."""

import json

from envcap.cli import main
from envcap.formats.registry import default_writer_names


def test_capture_writes_the_opt_in_engine_files(tmp_path):
    assert not {"webgl2", "latlong"} & set(default_writer_names())
    base = ["capture", "canyon", "--resolution", "8", "--spacing", "100", "--quiet"]
    assert main(base + ["--out", str(tmp_path / "eng"), "--webgl2", "--latlong"]) == 0
    files = json.loads((tmp_path / "eng" / "manifest.json").read_text())["files"]
    assert files["probes_atlas"] == "probes_atlas.ktx2" and (tmp_path / "eng" / "probes_atlas.ktx2").is_file()
    assert files["latlong_sky"] == "latlong/sky.exr"
    assert all((tmp_path / "eng" / f).is_file() for f in files["latlong"])
    assert len(files["latlong"]) == len(list((tmp_path / "eng" / "latlong").glob("probe_*.exr")))
