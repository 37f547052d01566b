"""The bake straight into a directory (``envcap capture``): the same bytes as baking, then
writing, with the per-probe files written on threads during the bake; chunked capture and
filtering that do not move a bit; progress lines on stderr."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

import envcap.probeset.bake as bake_module
from envcap.core.lobes import lobe_ladder
from envcap.prefilter import prefilter_many
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.bake_output import bake_to_directory
from envcap.probeset.progress import BakeProgress
from envcap.probeset.store import write_probe_set
from envcap.scene import load_scene

BAKE = dict(resolution=8, spacing=20.0)  # planes: 10 probes, more than one capture chunk (8)


def _tree(root):
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_threaded_files_and_chunks_give_the_bytes_of_bake_then_write(tmp_path, gl_ctx):
    scene = load_scene("planes")
    old = write_probe_set(tmp_path / "old", bake_probe_set(scene, ctx=gl_ctx, progress=False, **BAKE))
    lines = io.StringIO()
    new, ps = bake_to_directory(scene, tmp_path / "new", exr=True, previews=True, ctx=gl_ctx,
                                report=BakeProgress("lines", lines), **BAKE)
    assert ps.layer_count == 10
    a, b = _tree(old), _tree(new)
    assert sorted(a) == sorted(b) and len([k for k in a if k.startswith("exr/")]) == 10
    assert len([k for k in a if k.startswith("previews/probe_")]) == 10
    for name in a:
        if name != "manifest.json":
            assert a[name] == b[name], name
    ma, mb = (json.loads(x["manifest.json"]) for x in (a, b))
    ma.pop("timings"), mb.pop("timings")
    assert ma == mb
    text = lines.getvalue()
    for stage in ("sky", "capture: 10 probes", "prefilter: 10 probes", "write files: 10 probes", "write ktx2: 10 probes"):
        assert f"progress: {stage}" in text, text


def test_prefilter_chunks_are_the_filters_own_batches(gl_ctx, monkeypatch):
    """With batches of 2 probes the bake filters 4 probes at a time and gets what one call gets
    (``default`` quality: its footprint truncation follows a batch's dynamic range)."""
    batch = 6 * 8 * 8 * 16 * 2
    monkeypatch.setattr(bake_module, "PREFILTER_BATCH_BYTES", batch)
    monkeypatch.setattr(bake_module, "PREFILTER_CHUNK_PROBES", 3)
    ps = bake_probe_set(load_scene("canyon"), resolution=8, spacing=60.0, ctx=gl_ctx,
                        report=BakeProgress("lines", io.StringIO()))
    assert ps.layer_count > 4
    want = prefilter_many(ps.levels[0], lobe_ladder(8), ctx=gl_ctx, progress=False, batch_bytes=batch)
    for k, (got, ref) in enumerate(zip(ps.levels, want)):
        np.testing.assert_array_equal(got, ref, err_msg=f"level {k}")


def test_progress_modes():
    out = io.StringIO()
    rep = BakeProgress("auto", out)          # a StringIO is not a terminal: lines
    assert rep.mode == "lines"
    with rep.stage("capture", 3):
        rep.advance(2)
        rep.advance(1)
    assert out.getvalue().startswith("progress: capture: 3 probes in ") and "probes/s" in out.getvalue()
    quiet = io.StringIO()
    rep = BakeProgress("off", quiet)
    with rep.stage("prefilter", 5):
        rep.advance(5)
    assert quiet.getvalue() == "" and rep.seconds["prefilter"] >= 0
    bar = io.StringIO()
    rep = BakeProgress("bar", bar)           # what a terminal gets: a tqdm bar per stage
    with rep.stage("prefilter", 4):
        rep.advance(4)
    assert "prefilter: 100%" in bar.getvalue() and "4/4" in bar.getvalue() and "probe/s" in bar.getvalue()
    with pytest.raises(ValueError, match="progress mode"):
        BakeProgress("loud")  # type: ignore[arg-type]
