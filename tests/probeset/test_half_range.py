"""Issue 9: probe radiance past the half-float range of probes.ktx2 is named before the prefilter.

Old behaviour: a lit window of 202159 (the scene's range allowed up to 10^12) or a sun strong
enough to light a facade past 65504 let the whole bake run; writing ``probes.ktx2`` (RGBA16F)
then failed with "level 0: 2 value(s) exceed the half-float maximum 65504 ...; use fmt='rgba32f'
or clamp=True" (Python advice to a CLI user), naming neither the scene key nor the file.  New: a
window emission past 65504 is refused when the scene is parsed; what only the capture can tell
(sunlight on a bright albedo, emission plus reflected light) is checked on level 0 right after
the capture, in one line naming the probe, the peak, the limit and the likely cause; nothing is
clamped and nothing is written.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from envcap.cli import main
from envcap.probeset.half_range import check_half_range
from envcap.scene import load_scene

HALF_MAX = 65504.0  # the largest finite IEEE 754 binary16 value, (2 - 2^-10) * 2^15

SUN_SCENE = """\
name = "hot"
effects = ["sun_light"]
[sky]
type = "uniform"
radiance = 1000.0
sun = { elevation_deg = 90.0, illuminance = 1.0e6 }
[ground]
albedo = 0.5
[[streets]]
name = "main"
axis = "x"
start = -10.0
end = 10.0
width = 8.0
"""

WINDOW_SCENE = """\
name = "bright_windows"
effects = ["sun_light", "sky_light", "emissive_windows"]
[sky]
type = "uniform"
radiance = 2000.0
sun = { elevation_deg = 30.0, azimuth_deg = 0.0, illuminance = 1.0e5 }
[[streets]]
name = "main"
axis = "x"
start = -10.0
end = 10.0
width = 4.0
[streets.facade.windows]
width = 2.6
height = 2.8
spacing = 3.0
floor_height = 3.2
sill = 0.2
albedo = [0.9, 0.9, 0.9]
emissive_fraction = 1.0
emission = [%s, 65000.0, 65000.0]
[streets.side_min]
buildings = [{ width = 20.0, height = 12.0 }]
[streets.side_max]
buildings = [{ width = 20.0, height = 12.0 }]
"""

MESSAGE = re.compile(r"envcap: error: (?P<file>\S+): probe 0 of street 'main' at \(0, 2, 0\) m: radiance (?P<peak>[0-9.e+]+) "
                     r"is past 65504, the largest half float that probes\.ktx2 \(RGBA16F\) stores; "
                     r"likely cause: (?P<cause>.*) \(nothing clamped, nothing written\)$")


def _capture(tmp_path: Path, text: str, capsys) -> tuple[int, str, Path]:
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    out = tmp_path / "out"
    rc = main(["capture", str(scene), "--out", str(out), "--resolution", "8", "--spacing", "100"])
    return rc, capsys.readouterr().err.strip().splitlines()[-1], out


def _nothing_written(tmp_path: Path) -> None:
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]  # no --out, no temporary folder


def test_a_sun_that_lights_the_ground_past_half_float_is_named_before_the_prefilter(tmp_path, capsys):
    """A 10^6 lux sun straight overhead on ground of albedo 0.5: Lambert gives 0.5 * 10^6 / pi =
    159155 on the probe's down face (old: the whole bake, then "use fmt='rgba32f' or clamp=True")."""
    rc, line, out = _capture(tmp_path, SUN_SCENE, capsys)
    m = MESSAGE.match(line)
    assert rc == 2 and m, line
    assert m["file"].endswith("scene.toml")
    assert float(m["peak"]) == pytest.approx(0.5 * 1.0e6 / math.pi, rel=1e-5)
    assert m["cause"].startswith("sunlight up to 1.59e+05 (sun illuminance 1e+06 lux x albedo 0.5 / pi)")
    assert m["cause"].endswith("lower sky.sun.illuminance or the albedos")
    assert not out.exists()
    _nothing_written(tmp_path)


def test_a_window_within_range_plus_reflected_sunlight_names_the_emission(tmp_path, capsys):
    """Emission 65000 (within its range) on glass of albedo 0.9 facing a 10^5 lux sun 30 degrees
    up, under a uniform sky of 2000: 65000 + 0.9 * 10^5 cos(30) / pi + 0.9 * 2000 / 2 (the sky's
    upper hemisphere on a vertical wall) = 90709."""
    rc, line, out = _capture(tmp_path, WINDOW_SCENE % "65000.0", capsys)
    m = MESSAGE.match(line)
    assert rc == 2 and m, line
    expected = 65000.0 + 0.9 * 1.0e5 * math.cos(math.radians(30.0)) / math.pi + 0.9 * 2000.0 / 2
    assert float(m["peak"]) == pytest.approx(expected, rel=1e-4)
    # the estimates are upper bounds: the sun at normal incidence (0.9 * 10^5 / pi), the sky over a
    # whole hemisphere (0.9 * 2000)
    assert m["cause"].startswith("lit windows up to 6.5e+04 (window emission up to 65000; sunlight up to 2.86e+04; "
                                 "sky light up to 1.8e+03)")
    assert m["cause"].endswith("lower windows.emission")
    _nothing_written(tmp_path)


def test_an_emission_that_no_half_float_holds_is_refused_when_the_scene_is_parsed(tmp_path, capsys):
    """Old: 202159 passed the scene's range (10^12) and failed after the whole bake."""
    rc, line, out = _capture(tmp_path, WINDOW_SCENE % "202159.0", capsys)
    assert rc == 2 and "streets[0].facade.windows.emission" in line and "<= 65504" in line, line
    assert "probes on" not in capsys.readouterr().err  # nothing was placed, let alone captured
    _nothing_written(tmp_path)


def test_the_check_names_the_brightest_probe_and_lets_65504_through(tmp_path):
    """On a hand-made level 0 of three probes: 65504 itself is storable; past it, the brightest
    probe is named with its street, index and position, and the others past it are counted."""
    path = tmp_path / "scene.toml"
    path.write_text(SUN_SCENE)
    scene = load_scene(str(path))
    sky = scene.sky.build()
    probes = [("main", 0), ("main", 1), ("side", 0)]
    positions = np.array([[0.0, 2.0, 0.0], [5.0, 2.0, 0.0], [1.5, 3.0, -7.25]])
    rgba = np.zeros((3, 6, 4, 4, 4), np.float32)
    rgba[..., 3] = 1.0
    rgba[1, 2, 3, 3, 0] = HALF_MAX
    rgba[0, 5, 0, 1, 2] = np.nan  # left to the probe-set checks, not taken for the peak
    check_half_range(rgba, probes, positions, scene, sky)
    rgba[0, 4, 1, 1, 1] = 70000.0
    rgba[2, 0, 2, 0, 2] = 1.0e6
    with pytest.raises(ValueError) as info:
        check_half_range(rgba, probes, positions, scene, sky)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}: probe 0 of street 'side' at (1.5, 3, -7.25) m (and 1 more probe(s)): radiance 1e+06 "
                          "is past 65504"), msg
