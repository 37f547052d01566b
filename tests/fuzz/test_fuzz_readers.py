"""Fuzz the readers with mutated valid files: KTX2 (``read_ktx2``), OpenEXR cube maps
(``read_exr_cube``), whole probe sets (``read_probe_set``: manifest, KTX2, EXR), and the same
files as the CLI meets them (``envcap prefilter`` of a mutated EXR, ``envcap evaluate`` of a
mutated probe set).

Mutations: byte flips, byte sets, insertions, deletions, truncation and appended junk (mostly in
the header); one KTX2 header field or level-index entry or one OpenEXR header attribute set to
an edge value; texels set to NaN, Inf, negative or huge values; manifest values replaced
(1e300, NaN, wrong types, missing keys).  The valid originals are the session's probe set
(``planes``, 8^2, 4 probes, 4 levels).

Property (fuzz_harness): a one-line ``ValueError``/``OSError`` naming the file, or data that
agree with the header; where a reader promises finite data (``read_exr_cube``,
``read_probe_set``, every CLI output) it must be finite and, for radiance, not negative.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from fuzz_harness import (
    PINNED,
    Outcome,
    fuzz_settings,
    require_finite,
    require_names,
    run_case,
    settle,
)
from fuzz_known import known_issue
from fuzz_mutate import (
    ktx2_with_texel,
    mutated_bytes,
    mutated_exr_attribute,
    mutated_ktx2_field,
    mutated_tree,
    numbers,
)
from fuzz_sandbox import sandbox
from hypothesis import example, given
from hypothesis import strategies as st

from envcap.cli import main
from envcap.formats.exr_cube import read_exr_cube
from envcap.formats.ktx2 import read_ktx2
from envcap.probeset.store import read_probe_set
from envcap.runtime.street import RuntimeStreet

pytestmark = pytest.mark.slow  # property-based: up to tens of seconds per test

F32_MAX = float(np.finfo(np.float32).max)


def require_radiance(res: Outcome, levels, what: str) -> None:
    """Finite, and RGB not negative (premultiplied radiance), at every level."""
    require_finite(res, levels, what)
    for k, a in enumerate(levels):
        a = np.asarray(a)
        if a.size and np.nanmin(a[..., :3]) < 0:
            res.violate(f"wrong: {what}[{k}] holds negative radiance {float(np.nanmin(a[..., :3]))}")
            return


# --------------------------------------------------------------------------------------------
# KTX2


@st.composite
def ktx2_files(draw, baked: Path):
    name = draw(st.sampled_from(["probes.ktx2", "sky.ktx2"]))
    data = (baked / name).read_bytes()
    how = draw(st.sampled_from(["bytes", "field", "field", "texel"]))
    if how == "bytes":
        new, log = draw(mutated_bytes(data, hot=256))
    elif how == "field":
        new, log = draw(mutated_ktx2_field(data))
    else:
        new, log = draw(ktx2_with_texel(data))
    return name, new, log


def check_ktx2(fuzz_base: Path, name: str, data: bytes, log: list[str], tolerate: bool) -> None:
    with sandbox(fuzz_base) as sb:
        path = sb.write(name, data)
        res = run_case(sb, lambda: read_ktx2(path), inputs=[path])
        if res.ok:
            levels, info = res.value
            n, L = info["size"], info["layers"]
            for k, a in enumerate(levels):
                want = ((L,) if L else ()) + (6, max(1, n >> k), max(1, n >> k), 4)
                if a.shape != want or a.dtype != np.float32:
                    res.violate(f"wrong: level {k} has shape {a.shape} {a.dtype}, header says {want}")
        require_names(res, name)
        settle("read.ktx2", (name, log), res, known=known_issue if tolerate else None)


@fuzz_settings(60)
@given(data=st.data())
def test_mutated_ktx2_reads_or_fails_in_one_line(fuzz_base, baked, data):
    """``read_ktx2`` does not promise finite texels (``read_probe_set`` does): shapes only here."""
    name, new, log = data.draw(ktx2_files(baked))
    check_ktx2(fuzz_base, name, new, log, tolerate=True)


# --------------------------------------------------------------------------------------------
# OpenEXR cube maps


def exr_with_texels(src: Path, dst: Path, edits: list[tuple[str, int, float]], half: bool) -> None:
    """Copy a cube EXR with texel values replaced: ``(channel, flat index, value)``; half or float32."""
    with OpenEXR.File(str(src), separate_channels=True) as f:
        chans = {k: np.array(c.pixels, dtype=np.float16 if half and k != "Z" else np.float32)
                 for k, c in f.channels().items()}
    for ch, i, v in edits:
        a = chans[ch].reshape(-1)
        with np.errstate(over="ignore"):
            a[i % a.size] = v
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_CUBE}
    OpenEXR.File(header, chans).write(str(dst))


TEXEL_VALUES = [np.nan, np.inf, -np.inf, -1.0, -11.1, -1e-3, 65504.0, 1e9, 3e38]


@st.composite
def exr_cases(draw, baked: Path):
    """``(mode, bytes or texel edits, log)``."""
    src = baked / "exr" / "probe_000.exr"
    how = draw(st.sampled_from(["bytes", "attribute", "attribute", "texel"]))
    if how == "bytes":
        new, log = draw(mutated_bytes(src.read_bytes(), hot=400))
        return "bytes", new, log
    if how == "attribute":
        new, log = draw(mutated_exr_attribute(src.read_bytes()))
        return "bytes", new, log
    edits = draw(st.lists(st.tuples(st.sampled_from("RGBAZ"), st.integers(0, 383), st.sampled_from(TEXEL_VALUES)),
                          min_size=1, max_size=3))
    half = draw(st.booleans())
    return "texel", (edits, half), [f"{c}[{i}] = {v}" for c, i, v in edits] + [f"half={half}"]


def _materialize_exr(sb, baked: Path, mode: str, payload) -> Path:
    path = sb.path("probe.exr")
    if mode == "bytes":
        path.write_bytes(payload)
    else:
        edits, half = payload
        exr_with_texels(baked / "exr" / "probe_000.exr", path, edits, half)
    return path


def check_exr(fuzz_base: Path, baked: Path, mode: str, payload, log: list[str], tolerate: bool) -> None:
    with sandbox(fuzz_base) as sb:
        path = _materialize_exr(sb, baked, mode, payload)
        res = run_case(sb, lambda: read_exr_cube(path), inputs=[path])
        if res.ok:
            rgba, dist = res.value
            require_radiance(res, [rgba], "rgba")
            if dist is not None:
                require_finite(res, dist, "distance")
                if np.any(dist < 0):
                    res.violate(f"wrong: negative distance {float(dist.min())}")
        require_names(res, "probe.exr")
        settle("read.exr", (mode, log), res, known=known_issue if tolerate else None)


@fuzz_settings(50)
@given(data=st.data())
def test_mutated_exr_reads_or_fails_in_one_line(fuzz_base, baked, data):
    mode, payload, log = data.draw(exr_cases(baked))
    check_exr(fuzz_base, baked, mode, payload, log, tolerate=True)


# --------------------------------------------------------------------------------------------
# Whole probe sets (manifest + KTX2 + EXR)


def _manifest_numbers() -> st.SearchStrategy:
    return st.one_of(numbers(), st.sampled_from([1e300, -1e300, 3.5e38, 1e39, 1e30, -0.0]))


@st.composite
def probe_set_cases(draw, baked: Path):
    """``(file changed, new bytes, log)`` for one file of the probe set."""
    target = draw(st.sampled_from(["manifest.json", "manifest.json", "manifest.json", "probes.ktx2", "sky.ktx2",
                                   "exr/probe_001.exr"]))
    data = (baked / target).read_bytes()
    if target == "manifest.json":
        if draw(st.integers(0, 4)):
            tree, log = draw(mutated_tree(json.loads(data), max_ops=2))
            if draw(st.booleans()):  # a number in a position or a plane: float32 overflow, NaN
                st_ = tree.get("streets") if isinstance(tree, dict) else None
                if isinstance(st_, list) and st_ and isinstance(st_[0], dict) and isinstance(st_[0].get("probes"), list) \
                        and st_[0]["probes"] and isinstance(st_[0]["probes"][0], dict):
                    pr = st_[0]["probes"][0]
                    key = draw(st.sampled_from(["position", "planes"]))
                    v = draw(_manifest_numbers())
                    if key == "position" and isinstance(pr.get("position"), list) and len(pr["position"]) == 3:
                        pr["position"][draw(st.integers(0, 2))] = v
                        log.append(f"streets.0.probes.0.position[i] = {v!r}")
                    elif isinstance(pr.get("planes"), dict):
                        k = draw(st.sampled_from(["facade_min", "facade_max", "ground"]))
                        pr["planes"][k] = v
                        log.append(f"streets.0.probes.0.planes.{k} = {v!r}")
            return target, json.dumps(tree, indent=1).encode(), log
        new, log = draw(mutated_bytes(data, hot=len(data)))
        return target, new, log
    if target.endswith(".ktx2"):
        how = draw(st.sampled_from(["bytes", "field", "texel", "texel"]))
        new, log = draw({"bytes": mutated_bytes(data), "field": mutated_ktx2_field(data), "texel": ktx2_with_texel(data)}[how])
        return target, new, log
    new, log = draw(st.one_of(mutated_bytes(data, hot=400), mutated_exr_attribute(data)))
    return target, new, log


def check_probe_set(fuzz_base: Path, baked: Path, target: str, data: bytes, log: list[str], tolerate: bool) -> None:
    with sandbox(fuzz_base) as sb:
        root = sb.copy(baked, "set")
        (root / target).write_bytes(data)

        def read():
            ps = read_probe_set(root)
            m = ps.manifest
            streets = [RuntimeStreet.from_manifest(s) for s in (m.streets if hasattr(m, "streets") else m["streets"])]
            return ps, streets

        res = run_case(sb, read, inputs=[root])
        if res.ok:
            ps, streets = res.value
            require_radiance(res, ps.levels, "probe levels")
            require_radiance(res, ps.sky_levels, "sky levels")
            require_finite(res, ps.distance, "distance")
            require_finite(res, [(s.positions, s.planes) for s in streets], "streets (float32 range)")
        require_names(res, Path(target).name, "manifest", "probes.ktx2", "sky.ktx2")
        settle("read.probe_set", (target, log), res, known=known_issue if tolerate else None)


@fuzz_settings(60)
@given(data=st.data())
def test_mutated_probe_set_reads_or_fails_in_one_line(fuzz_base, baked, data):
    target, new, log = data.draw(probe_set_cases(baked))
    check_probe_set(fuzz_base, baked, target, new, log, tolerate=True)


# --------------------------------------------------------------------------------------------
# The same files through the CLI: envcap prefilter (EXR) and envcap evaluate (probe set)


def check_prefilter_cli(fuzz_base: Path, baked: Path, mode: str, payload, log: list[str], tolerate: bool) -> None:
    with sandbox(fuzz_base) as sb:
        path = _materialize_exr(sb, baked, mode, payload)
        out = sb.path("chain")
        res = run_case(sb, lambda: main(["prefilter", str(path), "--out", str(out)]), cli=True, out=out, inputs=[path])
        if res.ok:
            levels, _ = read_ktx2(out / "chain.ktx2")
            require_radiance(res, levels, "chain.ktx2")
        require_names(res, "probe.exr")
        settle("cli.prefilter_input", (mode, log), res, known=known_issue if tolerate else None)


@fuzz_settings(20)
@given(data=st.data())
def test_prefilter_of_a_mutated_exr_runs_or_fails_in_one_line(fuzz_base, baked, data):
    mode, payload, log = data.draw(exr_cases(baked))
    check_prefilter_cli(fuzz_base, baked, mode, payload, log, tolerate=True)


def check_evaluate_cli(fuzz_base: Path, baked: Path, target: str, data: bytes, log: list[str], tolerate: bool) -> None:
    with sandbox(fuzz_base) as sb:
        root = sb.copy(baked, "set")
        (root / target).write_bytes(data)
        out = sb.path("report")
        argv = ["evaluate", "planes", "--probes", str(root), "--out", str(out), "--positions", "1", "--resolution", "4",
                "--methods", "nearest", "--lobes", "inf,1", "--no-images"]
        res = run_case(sb, lambda: main(argv), cli=True, out=out, inputs=[root])
        if res.ok:
            report = json.loads(next(out.glob("*.json")).read_text()) if list(out.glob("*.json")) else {}
            require_finite(res, report, "report")
        require_names(res, Path(target).name, "manifest", "probes.ktx2", "sky.ktx2")
        settle("cli.evaluate_input", (target, log), res, known=known_issue if tolerate else None)


@fuzz_settings(10)
@given(data=st.data())
def test_evaluate_of_a_mutated_probe_set_runs_or_fails_in_one_line(fuzz_base, baked, data):
    target, new, log = data.draw(probe_set_cases(baked))
    check_evaluate_cli(fuzz_base, baked, target, new, log, tolerate=True)


# --------------------------------------------------------------------------------------------
# Pinned: each failure found today, its reproducer first (strict xfail until the fix lands)


def _ktx2_texel(baked: Path, name: str, component: int, value: float) -> bytes:
    import struct

    from fuzz_mutate import ktx2_level0

    data = bytearray((baked / name).read_bytes())
    off, _, size = ktx2_level0(bytes(data))
    struct.pack_into("<e" if size == 2 else "<f", data, off + size * component, value)
    return bytes(data)


@PINNED
@example(name="probes.ktx2", value=float("nan"))
@given(name=st.sampled_from(["probes.ktx2", "sky.ktx2"]), value=st.sampled_from([float("inf"), -1.0, float("-inf")]))
def test_pinned_nan_or_negative_texels_in_a_probe_set_are_refused(fuzz_base, baked, name, value):
    """Issue 9 item 4: NaN texels in probes.ktx2 pass the reader (and evaluate fails later, naming no file)."""
    data = _ktx2_texel(baked, name, 0, value)
    check_probe_set(fuzz_base, baked, name, data, [f"{name} level 0 component 0 = {value}"], tolerate=False)
    check_evaluate_cli(fuzz_base, baked, name, data, [f"{name} level 0 component 0 = {value}"], tolerate=False)


@PINNED
@example(value=1e300)
@given(value=st.sampled_from([3.5e38, -1e39, 1e308]))
def test_pinned_a_manifest_position_past_float32_is_refused(fuzz_base, baked, value):
    """Issue 9 item 4: a probe position of 1e300 passes the finite check and overflows float32."""
    m = json.loads((baked / "manifest.json").read_text())
    m["streets"][0]["probes"][0]["position"][0] = value
    check_probe_set(fuzz_base, baked, "manifest.json", json.dumps(m).encode(),
                    [f"streets.0.probes.0.position[0] = {value}"], tolerate=False)


@PINNED
@example(channel="R", value=-11.1)
@given(channel=st.sampled_from("GBZ"), value=st.sampled_from([-1.0, -1e-3]))
def test_pinned_negative_texels_in_a_cube_exr_are_refused(fuzz_base, baked, channel, value):
    """Issue 9 item 4: a cube EXR with negative texels was accepted and prefiltered into negative
    radiance (old: level 1 held -11.1); now read_exr_cube, the door every reader uses, refuses
    negative R, G, B and Z with their count."""
    payload = ([(channel, 5, value)], False)
    check_exr(fuzz_base, baked, "texel", payload, [f"{channel}[5] = {value}"], tolerate=False)
    check_prefilter_cli(fuzz_base, baked, "texel", payload, [f"{channel}[5] = {value}"], tolerate=False)


@PINNED
@example(pos=233)
@given(pos=st.sampled_from([30, 150, 300]))
def test_pinned_a_non_utf8_header_byte_names_the_exr_file(fuzz_base, baked, pos):
    """Byte 233 (in the header's ``envmap`` attribute name) set to 0x80: old, read_exr_cube raised
    the codec's "'utf-8' codec can't decode byte 0x80 in position 23", naming no file; now one line
    naming the file ("corrupt OpenEXR header")."""
    data = bytearray((baked / "exr" / "probe_000.exr").read_bytes())
    data[pos] = 0x80
    check_exr(fuzz_base, baked, "bytes", bytes(data), [f"byte {pos} = 0x80"], tolerate=False)
