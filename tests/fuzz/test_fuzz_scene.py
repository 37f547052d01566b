"""Fuzz the TOML scene format: the bundled scenes, mutated (as parsed trees and as bytes), loaded
with ``envcap.scene.load_scene`` and taken as far as the bake takes them before rendering (the
sky, its cube, the probe placement); a few also captured through the CLI.

Property (fuzz_harness): finite output (mesh, streets, sky cube, probe positions, all within
float32) or a one-line ``ValueError``/``OSError`` naming the file or the key; no traceback, no
runaway, nothing left behind.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from fuzz_harness import (
    PINNED,
    fuzz_settings,
    require_finite,
    require_names,
    run_case,
    settle,
)
from fuzz_known import known_issue
from fuzz_mutate import mutated_bytes, mutated_tree, to_toml
from fuzz_sandbox import sandbox
from hypothesis import example, given
from hypothesis import strategies as st

from envcap.cli import main
from envcap.core.resources import city_scenes_dir
from envcap.probeset.placement import place_probes
from envcap.probeset.store import read_probe_set
from envcap.scene import load_scene

pytestmark = pytest.mark.slow  # property-based: up to tens of seconds per test

SCENES = {p.stem: p for p in sorted(city_scenes_dir().glob("*.toml"))}
TREES = {name: tomllib.loads(p.read_text()) for name, p in SCENES.items()}


@st.composite
def scene_files(draw: st.DrawFn) -> tuple[str, bytes, list[str]]:
    """``(bundled scene, mutated file bytes, what changed)``: 3 in 4 edit the parsed tree, 1 in 4 the bytes."""
    name = draw(st.sampled_from(sorted(SCENES)))
    if draw(st.integers(0, 3)):
        tree, log = draw(mutated_tree(TREES[name]))
        return name, to_toml(tree).encode(), log
    data, log = draw(mutated_bytes(SCENES[name].read_bytes(), hot=4096))
    return name, data, log


def _keys(log: list[str]) -> list[str]:
    """Key names a good message could cite, from the mutation log (``streets.0.width = 1e30`` -> width, streets)."""
    out = []
    for entry in log:
        head = entry.split(" ", 2)[1] if entry.startswith(("del ", "dup ")) else entry.split(" ", 1)[0]
        out += [k for k in head.split(".") if k and not k.isdigit()]
        if "zzz_unknown" in entry:
            out.append("zzz_unknown")
    return out


def _prepare(sb, name: str, data: bytes, latlong_exr: Path) -> Path:
    path = sb.write("scene.toml", data)
    if name == "imported":
        sb.copy(SCENES[name].parent / "imported_block", "imported_block")
    sb.copy(latlong_exr, "sky.exr")  # for mutations that turn the sky into a lat-long file
    return path


def check_scene(fuzz_base: Path, latlong_exr: Path, name: str, data: bytes, log: list[str], *, tolerate: bool,
                timeout: float = 10.0) -> None:
    with sandbox(fuzz_base) as sb:
        path = _prepare(sb, name, data, latlong_exr)

        def build():
            scene = load_scene(path)
            sky = scene.sky.build()
            cube = sky.cube(2)
            placed = [place_probes(s) for s in scene.streets]
            return scene, cube, placed

        res = run_case(sb, build, inputs=[path], timeout=timeout)
        if res.ok:
            scene, cube, placed = res.value
            require_finite(res, scene.mesh.positions, "mesh.positions")
            require_finite(res, [(s.start, s.end, s.facade_min, s.facade_max, s.ground, s.center_line) for s in scene.streets],
                           "streets")
            require_finite(res, cube, "sky cube")
            require_finite(res, [p.position for ps in placed for p in ps], "probe positions")
        require_names(res, "scene.toml", "sky", *_keys(log))
        settle("scene.load", (name, log), res, known=known_issue if tolerate else None)


@fuzz_settings(40)
@given(case=scene_files())
def test_mutated_scene_loads_or_fails_in_one_line(fuzz_base, latlong_exr, case):
    name, data, log = case
    check_scene(fuzz_base, latlong_exr, name, data, log, tolerate=True)


def check_scene_capture(fuzz_base: Path, latlong_exr: Path, name: str, data: bytes, log: list[str], *,
                        tolerate: bool) -> None:
    with sandbox(fuzz_base) as sb:
        path = _prepare(sb, name, data, latlong_exr)
        out = sb.path("out")
        argv = ["capture", str(path), "--out", str(out), "--resolution", "4", "--spacing", "1000", "--no-previews"]
        res = run_case(sb, lambda: main(argv), out=out, inputs=[path], cli=True, timeout=20)
        if res.ok:
            require_finite(res, read_probe_set(out).levels, "probe levels")
        require_names(res, "scene.toml", "sky", *_keys(log))
        settle("scene.capture", (name, log), res, known=known_issue if tolerate else None)


@fuzz_settings(6)
@given(case=scene_files())
def test_mutated_scene_captures_or_fails_in_one_line(fuzz_base, latlong_exr, case):
    """The whole capture at 4^2 on one or two probes per street: the mutated scene through the CLI."""
    name, data, log = case
    check_scene_capture(fuzz_base, latlong_exr, name, data, log, tolerate=True)


# --------------------------------------------------------------------------------------------
# Pinned: each failure found today, its reproducer first (strict xfail until the fix lands)


def _edit(name: str, edit) -> bytes:
    tree = tomllib.loads(SCENES[name].read_text())
    edit(tree)
    return to_toml(tree).encode()


def _set_random(side: str, key: str, value):
    def edit(tree):
        tree["streets"][0][side]["random"][key] = value
    return edit


@PINNED
@example(big=10**400)
@given(big=st.integers(2**1024, 2**1100))
def test_pinned_an_int_past_float_range_is_one_line(fuzz_base, latlong_exr, big):
    """``depth = 1e400`` written as an integer (old: ``OverflowError`` from ``float(v)``, a traceback)."""
    data = _edit("asymmetric", _set_random("side_min", "depth", [big, big]))
    check_scene(fuzz_base, latlong_exr, "asymmetric", data, ["streets.0.side_min.random.depth"], tolerate=False)


@PINNED
@example(key="width", value=[1e-6, 1e-6])
@given(key=st.sampled_from(["height", "width"]), value=st.sampled_from([[1e7, 1.05e7], [1e-5, 1e-5], [1e30, 1e31]]))
def test_pinned_absurd_building_sizes_are_refused_at_once(fuzz_base, latlong_exr, key, value):
    """Random buildings 10^-6 m wide (10^8 buildings over 600 m) or 10^7 m tall (10^6 windows
    each): bounds before work refuse them in one line (old: minutes of work or a MemoryError)."""
    data = _edit("canyon", _set_random("side_min", key, value))
    check_scene(fuzz_base, latlong_exr, "canyon", data, [f"streets.0.side_min.random.{key}"], tolerate=False,
                timeout=2.5)


@PINNED
@example(scale=1e30)
@given(scale=st.sampled_from([1e25, 1e30, 1e36]))
def test_pinned_a_mesh_scale_past_float32_is_named(fuzz_base, latlong_exr, scale):
    """``[mesh] scale = 1e30`` (old: the bake ran and writing failed with 'distance must be finite')."""
    def edit(tree):
        tree["mesh"]["scale"] = scale
    check_scene_capture(fuzz_base, latlong_exr, "imported", _edit("imported", edit), ["mesh.scale"], tolerate=False)


@PINNED
@example(emission=202159.0)
@given(emission=st.sampled_from([7.0e4, 1.0e6]))
def test_pinned_probe_radiance_past_half_float_is_named_before_the_bake(fuzz_base, latlong_exr, emission):
    """A lit window of radiance 202159 (old: within the scene's range; the whole bake ran, then writing
    probes.ktx2 (RGBA16F) failed with "level 0: 2 value(s) exceed the half-float maximum 65504 ...;
    use fmt='rgba32f' or clamp=True" -- Python advice to a CLI user, naming neither the key nor the file).
    New: the emission's range ends at 65504, so the scene is refused at load naming the key."""
    def edit(tree):
        tree["streets"][0]["facade"]["windows"]["emission"] = [emission, 95.0, 60.0]
    check_scene_capture(fuzz_base, latlong_exr, "canyon", _edit("canyon", edit), ["streets.0.facade.windows.emission"],
                        tolerate=False)
