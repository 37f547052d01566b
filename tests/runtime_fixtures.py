"""Shared test helpers for the runtime tests: a small synthetic probe set (not a test module)."""

from __future__ import annotations

import numpy as np

from envcap import synthetic_street as ss
from envcap.lobes import lobe_ladder
from envcap.parallax import RuntimeStreet
from envcap.resources import shader_source

DECL = shader_source("envcap_street_uniforms.glsl")
ARGS = "along_s, pos, planes, count, along, xk, nlevels"


def probe_set(n=32, count=3, along=0, planes=(-6.0, 6.0, 0.0), start=0.0, end=20.0):
    """(probe_levels, sky_levels, street, powers): box-filtered chains of the analytic street."""
    pos = ss.probe_positions(start, end, count, planes, along)
    pl = np.tile(np.asarray(planes, float), (count, 1))
    lad = lobe_ladder(n)
    probes = ss.box_mips(ss.probe_cubes(pos, pl, along, n), lad.levels)
    sky = ss.box_mips(ss.sky_cube(n), lad.levels)
    street = RuntimeStreet(along, pos, pl, np.arange(count))
    return probes, sky, street, np.asarray(lad.powers)
