"""The probe-set writer registry: a writer registered from here lands in the output directory,
inside the same atomic write as envcap's own; selection, required writers, bad entries."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from envcap.formats.registry import WRITERS, default_writer_names, register_writer, select_writers, unregister_writer
from envcap.formats.writer import FileEntries, ProbeSetWriter
from envcap.outputs import MARKER_NAME
from envcap.probeset.manifest import Manifest, Planes, Probe, SkyInfo, Street, level_table
from envcap.probeset.probe_set import ProbeSet
from envcap.probeset.store import read_probe_set, write_probe_set

N = 4


def tiny_set() -> ProbeSet:
    """Two probes of 4^2 on one street along x, all geometry (alpha 1) at 5 m."""
    plan = Planes(-5.0, 5.0, 0.0)
    probes = (Probe(0, 0, (-2.0, 1.5, 0.0), plan, None, False), Probe(1, 1, (2.0, 1.5, 0.0), plan, None, False))
    m = Manifest(resolution=N, levels=level_table(N, 1), probe_height=1.5, probe_spacing=4.0,
                 streets=(Street("lane", "x", -4.0, 4.0, 0.0, plan, probes),), sky=SkyInfo({}))
    rgba = np.zeros((2, 6, N, N, 4), np.float32)
    rgba[0], rgba[1] = [1.0, 2.0, 3.0, 1.0], [4.0, 5.0, 6.0, 1.0]
    sky = np.ones((6, N, N, 4), np.float32)
    return ProbeSet(m, [rgba], np.full((2, 6, N, N), 5.0, np.float32), [sky])


def write_layers(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """A trivial writer: one line per probe, "<layer> <street> <x> <y> <z>"."""
    lines = [f"{p.layer} {st.name} {p.position[0]:g} {p.position[1]:g} {p.position[2]:g}"
             for st in ps.manifest.streets for p in st.probes]
    (out_dir / "layers.txt").write_text("\n".join(lines) + "\n")
    return {"layers": "layers.txt"}


@pytest.fixture
def layers_writer():
    w = register_writer(ProbeSetWriter("layers", "probe layers as text", write_layers, default=False))
    yield w
    unregister_writer("layers")


def test_a_writer_registered_here_writes_into_the_probe_set(tmp_path, layers_writer):
    assert "layers" in WRITERS and "layers" not in default_writer_names()
    out = write_probe_set(tmp_path / "set", tiny_set(), writers=["layers"])
    assert sorted(p.name for p in out.iterdir()) == [MARKER_NAME, "layers.txt", "manifest.json", "probes.ktx2", "sky.ktx2"]
    assert (out / "layers.txt").read_text() == "0 lane -2 1.5 0\n1 lane 2 1.5 0\n"
    back = read_probe_set(out)
    assert back.manifest.files.extra == {"layers": "layers.txt"} and back.manifest.files.probes == "probes.ktx2"
    assert back.distance is None  # the exr writer was not asked for
    # Asked for with the defaults: its entry comes after theirs, in registry order.
    out = write_probe_set(tmp_path / "all", tiny_set(), writers=[*default_writer_names(), "layers"])
    text = (out / "manifest.json").read_text()
    assert text.index('"contact_sheet"') < text.index('"layers": "layers.txt"')
    assert (out / "exr/probe_001.exr").is_file() and (out / "layers.txt").is_file()


def test_a_failing_writer_leaves_the_old_output_as_it_was(tmp_path):
    def half_then_fail(out_dir: Path, ps: ProbeSet) -> FileEntries:
        (out_dir / "partial.txt").write_text("half")
        raise OSError("disk full")

    old = write_probe_set(tmp_path / "set", tiny_set(), previews=False)
    before = {p.relative_to(old): p.read_bytes() for p in old.rglob("*") if p.is_file()}
    register_writer(ProbeSetWriter("failing", "fails half way", half_then_fail, default=False))
    try:
        with pytest.raises(OSError, match="disk full"):
            write_probe_set(tmp_path / "set", tiny_set(), writers=["failing"])
    finally:
        unregister_writer("failing")
    assert {p.relative_to(old): p.read_bytes() for p in old.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["set"]  # no temporary directory left


def test_selection_and_bad_writers(tmp_path, layers_writer):
    assert [w.name for w in select_writers([])] == ["ktx2"]  # required: the reader needs it
    assert [w.name for w in select_writers(["layers", "exr"])] == ["ktx2", "exr", "layers"]  # registry order
    with pytest.raises(ValueError, match=r"unknown probe-set writer\(s\) \['pngs'\]"):
        write_probe_set(tmp_path / "a", tiny_set(), writers=["pngs"])
    with pytest.raises(ValueError, match="already registered"):
        register_writer(ProbeSetWriter("exr", "a second exr", write_layers))
    register_writer(ProbeSetWriter("clash", "claims the probes entry", lambda d, ps: {"probes": "other.ktx2"}, default=False))
    register_writer(ProbeSetWriter("badentry", "a number is no path", lambda d, ps: {"count": 3}, default=False))
    try:
        with pytest.raises(ValueError, match=r"'clash': files entries \['probes'\] already written"):
            write_probe_set(tmp_path / "a", tiny_set(), writers=["clash"])
        with pytest.raises(ValueError, match="files.count: must be a path"):
            write_probe_set(tmp_path / "a", tiny_set(), writers=["badentry"])
    finally:
        unregister_writer("clash")
        unregister_writer("badentry")
    assert not (tmp_path / "a").exists()
