"""Probe-set directories: round trip, atomic failure, arrays checked against the manifest, bad inputs."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import OpenEXR
import pytest
from PIL import Image

from envcap.core.cube import texel_directions
from envcap.outputs import MARKER_NAME
from envcap.probeset.manifest import Files, Level, Manifest, Planes, Probe, SkyInfo, Street, level_table
from envcap.probeset.probe_set import ProbeSet
from envcap.probeset.store import read_probe_set, write_probe_set

N, NLEV = 8, 4


def street_probe(n: int, x0: float) -> tuple[np.ndarray, np.ndarray]:
    """Probe at (x0, 1.7, z) in a street along Z with facades at x = +-10 m, 15 m tall."""
    d = texel_directions(n)
    dx, dy = d[..., 0], d[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        tf = np.where(np.abs(dx) > 1e-9, (10.0 - np.sign(dx) * x0) / np.abs(dx), np.inf)
        tg = np.where(dy < -1e-9, 1.7 / -dy, np.inf)
    hit_f = (1.7 + tf * dy < 15.0) & (tf < tg)
    hit_g = np.isfinite(tg) & ~hit_f
    rgba = np.zeros(d.shape[:-1] + (4,))
    rgba[hit_f] = [900, 500, 350, 1]
    rgba[hit_g] = [300, 300, 320, 1]
    dist = np.where(hit_f, tf, np.where(hit_g, tg, 0.0))
    return rgba.astype(np.float32), dist.astype(np.float32)


def mips(a: np.ndarray, nlev: int) -> list[np.ndarray]:
    out = [a]
    for _ in range(nlev - 1):
        a = 0.25 * (a[..., 0::2, 0::2, :] + a[..., 1::2, 0::2, :] + a[..., 0::2, 1::2, :] + a[..., 1::2, 1::2, :])
        out.append(a.astype(np.float32))
    return out


def make_manifest(xs, resolution: int = N, nlev: int = NLEV) -> Manifest:
    plan = Planes(-10.0, 10.0, 0.0)
    probes = tuple(Probe(i, i, (float(x), 1.7, 0.0), plan, None, False) for i, x in enumerate(xs))
    levels = level_table(resolution, nlev)
    levels = (levels[0], Level(1, resolution >> 1, np.float32(64.0)), *levels[2:])  # numpy scalars are accepted
    return Manifest(resolution=resolution, levels=levels, probe_height=1.7, probe_spacing=4.0,
                    streets=(Street("main", "x", -5.0, 5.0, 0.0, plan, probes),),
                    effects=("sun_light",), passes_run=("sun_light",), sky=SkyInfo({}))


def make_set(layers: int = 3) -> ProbeSet:
    xs = np.linspace(-4, 4, layers)
    probes = [street_probe(N, x) for x in xs]
    arr = np.stack([p[0] for p in probes]).astype(np.float16).astype(np.float32)  # half-exact
    dist = np.stack([p[1] for p in probes])
    sky0 = np.ones((6, N, N, 4), np.float32) * 1000
    sky0[..., 3] = 1.0  # the sky covers everything: alpha 1
    sky0[2, 3, 4, :3] = 1.6e9  # the sun: beyond half range
    return ProbeSet(manifest=make_manifest(xs), levels=mips(arr, NLEV), distance=dist, sky_levels=mips(sky0, NLEV))


def test_roundtrip(tmp_path):
    ps = make_set()
    out = write_probe_set(tmp_path / "set", ps)
    names = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert names == [MARKER_NAME, "exr/probe_000.exr", "exr/probe_001.exr", "exr/probe_002.exr", "manifest.json",
                     "previews/contact_sheet.png", "previews/probe_000.png", "previews/probe_001.png",
                     "previews/probe_002.png", "previews/sky.png", "probes.ktx2", "sky.ktx2"]
    assert ps.manifest.files == Files()  # caller's manifest untouched
    back = read_probe_set(out)
    assert back.manifest.files.probes == "probes.ktx2"
    assert back.manifest.files.exr == ("exr/probe_000.exr", "exr/probe_001.exr", "exr/probe_002.exr")
    assert back.manifest.levels[1].lobe_power == 64.0
    assert back.manifest.streets[0].probes[2].position == (4.0, 1.7, 0.0)
    assert back.manifest.streets == ps.manifest.streets and back.manifest.levels == ps.manifest.levels
    for k in range(NLEV):
        assert back.levels[k].shape == (3, 6, N >> k, N >> k, 4)
        # probes.ktx2 is RGBA16F: exact for half-representable data, within half rounding otherwise
        assert np.allclose(back.levels[k], ps.levels[k], rtol=2.0**-11, atol=1e-6)
        assert np.array_equal(back.sky_levels[k], ps.sky_levels[k])  # RGBA32F: exact
    assert np.array_equal(back.levels[0], ps.levels[0])
    assert back.sky_levels[0].max() == np.float32(1.6e9)
    assert np.array_equal(back.distance, ps.distance)  # EXR Z is float32
    # The EXR on disk is an OpenEXR cube map with R, G, B, A, Z.
    with OpenEXR.File(str(out / "exr/probe_001.exr"), separate_channels=True) as f:
        assert f.header()["envmap"] == OpenEXR.ENVMAP_CUBE
        assert sorted(f.channels()) == ["A", "B", "G", "R", "Z"]
    assert Image.open(out / "previews/probe_000.png").size == (4 * N, 3 * N)
    # Without EXR and previews: no distance on read.
    out2 = write_probe_set(tmp_path / "lean", ps, exr=False, previews=False)
    assert sorted(p.name for p in out2.iterdir()) == [MARKER_NAME, "manifest.json", "probes.ktx2", "sky.ktx2"]
    assert read_probe_set(out2).distance is None


def test_failure_leaves_nothing_and_keeps_old_output(tmp_path):
    ps = make_set()
    bad = make_set()
    bad.levels[2] = bad.levels[2].copy()
    bad.levels[2][1, 3, 0, 0, 1] = np.nan
    with pytest.raises(ValueError, match=r"probe levels: layer 1, level 2: 1 of 24 texels are NaN/Inf"):
        write_probe_set(tmp_path / "set", bad)
    assert list(tmp_path.iterdir()) == []
    write_probe_set(tmp_path / "set", ps)
    before = (tmp_path / "set/manifest.json").read_text()
    over = make_set()
    over.levels = [lv * np.array([1e3, 1e3, 1e3, 1.0], np.float32) for lv in over.levels]  # RGB beyond half
    # range: passes the texel checks, fails inside the write (KTX2)
    with pytest.raises(ValueError, match="half-float maximum 65504"):
        write_probe_set(tmp_path / "set", over)
    assert (tmp_path / "set/manifest.json").read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["set"]  # no temp dirs left


def test_shapes_checked_against_manifest(tmp_path):
    ps = make_set()
    ps.levels = ps.levels[:3]
    with pytest.raises(ValueError, match="disagree with the manifest"):
        write_probe_set(tmp_path / "a", ps)
    ps = make_set(layers=2)
    st = ps.manifest.streets[0]
    extra = Probe(2, 2, (0.0, 1.7, 0.0), st.planes, None, False)
    ps.manifest = replace(ps.manifest, streets=(replace(st, probes=st.probes + (extra,)),))
    with pytest.raises(ValueError, match="2 layers but the manifest lists 3"):
        write_probe_set(tmp_path / "a", ps)
    ps = make_set()
    ps.distance = ps.distance.copy()
    sky_texel = np.argwhere(ps.levels[0][..., 3] == 0)[0]
    ps.distance[tuple(sky_texel)] = 5.0
    with pytest.raises(ValueError, match="0 where alpha is 0"):
        write_probe_set(tmp_path / "a", ps)
    ps = make_set()
    ps.manifest = ps.manifest.with_timings(capture_s=float("nan"))
    with pytest.raises(ValueError, match="strict JSON"):
        write_probe_set(tmp_path / "a", ps)
    assert list(tmp_path.iterdir()) == []


def test_read_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        read_probe_set(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="manifest.json missing"):
        read_probe_set(tmp_path / "empty")
    out = write_probe_set(tmp_path / "set", make_set(), previews=False)
    m = json.loads((out / "manifest.json").read_text())
    m["resolution"] = 16
    m["levels"] = [{"level": k, "size": 16 >> k, "lobe_power": None} for k in range(NLEV)]
    (out / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(ValueError, match="manifest says 3 probes x 4 levels of 16"):
        read_probe_set(out)
    (out / "manifest.json").write_text("{ not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        read_probe_set(out)
    out = write_probe_set(tmp_path / "set2", make_set(), previews=False)
    (out / "sky.ktx2").unlink()
    with pytest.raises(FileNotFoundError, match="sky.ktx2"):
        read_probe_set(out)
