"""The sky registry: a new sky model registered from this file (no envcap file touched) is named by a
scene TOML, loads, and renders its cube; the registry's generic key checks apply to it; built-in
``[sky]`` tables parse into typed parameters equal to the file's values, without reading files."""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from envcap.core import cube
from envcap.core.resources import city_scenes_dir
from envcap.scene import load_scene
from envcap.sky import SKY_MODELS, Sky, SkyModel, parse_sky_spec, register_sky, sky_from_spec
from envcap.core.checks import finite_float, unit_directions
from envcap.sky.latlong import LatLongParams
from envcap.sky.preetham import PreethamParams


# ---- a whole new sky model: this block is all it takes (plus one register_sky call) ----------------

class UniformGreySky(Sky):
    """Grey dome of ``level`` cd/m^2 in every direction, no sun."""

    def __init__(self, level: float) -> None:
        self.level = level

    def radiance(self, dirs: Any) -> np.ndarray:
        d = unit_directions(dirs)
        return np.full(d.shape, self.level)

    def spec(self) -> dict[str, Any]:
        return {"type": "uniform_grey", "level": self.level, "sun_light": None}


@dataclass(frozen=True)
class UniformGreyParams:
    """``level`` (required): the grey radiance, cd/m^2, >= 0."""

    level: float

    @classmethod
    def parse(cls, table: dict[str, Any], base_dir: Path | None = None) -> "UniformGreyParams":
        level = finite_float(table["level"], "sky.level")
        if level < 0:
            raise ValueError(f"sky.level must be non-negative, got {level:g}")
        return cls(level)

    def build(self) -> UniformGreySky:
        return UniformGreySky(self.level)


UNIFORM_GREY = SkyModel(name="uniform_grey", required=frozenset({"level"}), optional=frozenset(),
                        parse=UniformGreyParams.parse, build=UniformGreyParams.build)


@pytest.fixture
def uniform_grey():
    register_sky(UNIFORM_GREY)
    try:
        yield UNIFORM_GREY
    finally:
        del SKY_MODELS["uniform_grey"]


SCENE = """\
effects = ["sky_light"]
[sky]
type = "uniform_grey"
level = {level}
[[streets]]
axis = "x"
length = 40.0
width = 10.0
"""


def test_registered_sky_loads_from_a_scene_toml_and_renders_its_cube(uniform_grey, tmp_path):
    path = tmp_path / "grey.toml"
    path.write_text(SCENE.format(level=750.0))
    scene = load_scene(path)
    assert scene.sky.type == "uniform_grey" and scene.sky.params == UniformGreyParams(750.0)
    sky = scene.sky.build()
    assert isinstance(sky, UniformGreySky)
    for n in (1, 8):
        c = sky.cube(n)
        assert c.shape == (6, n, n, 3) and c.dtype == np.float32
        np.testing.assert_array_equal(c, np.float32(750.0))  # texel averages of a constant
        # Independent reference: the cube's exact texel solid angles integrate to 4 pi.
        e = np.sum(c.astype(np.float64) * cube.texel_solid_angles(n)[..., None], axis=(0, 1, 2))
        np.testing.assert_allclose(e, 4 * math.pi * 750.0, rtol=1e-12)
    assert sky_from_spec(sky.spec()).spec() == sky.spec()  # the manifest round trip


def test_registered_sky_gets_the_registry_key_checks(uniform_grey, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE.format(level=1.0).replace("level = 1.0", "level = 1.0\nlevle = 2.0"))
    with pytest.raises(ValueError, match=r"bad\.toml: sky \(uniform_grey\): unknown key\(s\) \['levle'\]; "
                                         r"allowed: \['level', 'sun_light', 'type'\]"):
        load_scene(bad)
    with pytest.raises(ValueError, match=r"missing key\(s\) \['level'\]"):
        sky_from_spec({"type": "uniform_grey"})
    with pytest.raises(ValueError, match="sky.level must be non-negative"):
        sky_from_spec({"type": "uniform_grey", "level": -1})
    with pytest.raises(ValueError, match="already registered"):
        register_sky(UNIFORM_GREY)


def test_unregistered_type_is_named_with_the_known_ones():
    assert "uniform_grey" not in SKY_MODELS
    with pytest.raises(ValueError, match=r"unknown type 'uniform_grey'; known: \['latlong', 'preetham', 'uniform'\]"):
        sky_from_spec({"type": "uniform_grey", "level": 1.0})
    with pytest.raises(ValueError, match="reserved"):
        register_sky(SkyModel("x", frozenset({"sun_light"}), frozenset(), UniformGreyParams.parse,
                              UniformGreyParams.build))
    assert "x" not in SKY_MODELS


def test_bundled_sky_tables_parse_into_the_files_values():
    for path in sorted(city_scenes_dir().glob("*.toml")):
        with open(path, "rb") as f:
            table = tomllib.load(f)["sky"]
        spec = load_scene(path.stem).sky
        assert spec.type == table["type"] == "preetham"
        p = spec.params
        assert isinstance(p, PreethamParams)
        assert (p.turbidity, p.sun_elevation_deg, p.sun_azimuth_deg) == (
            table["turbidity"], table["sun_elevation_deg"], table.get("sun_azimuth_deg", 0.0))
        assert type(p.turbidity) is float and p.scale == 1.0 and p.ground_albedo == 0.2


def test_parsing_reads_no_file_building_does(tmp_path):
    spec = parse_sky_spec({"type": "latlong", "file": "sub/none.exr", "scale": 2,
                            "sun": {"elevation_deg": 10, "illuminance": 5}}, base_dir=tmp_path)
    p = spec.params
    assert isinstance(p, LatLongParams)
    assert p.file == "sub/none.exr" and p.path == tmp_path / "sub" / "none.exr" and p.scale == 2.0
    assert p.sun is not None and p.sun.illuminance == (5.0, 5.0, 5.0) and p.sun.table == {"elevation_deg": 10, "illuminance": 5}
    with pytest.raises(FileNotFoundError, match="none.exr"):
        spec.build()
