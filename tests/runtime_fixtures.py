"""Shared test helpers for the runtime tests: a small synthetic probe set (not a test module)."""

from __future__ import annotations

from envcap.runtime import synthetic_street as ss
from envcap.core.resources import shader_source

DECL = shader_source("runtime/envcap_street_uniforms.glsl")
ARGS = "envcap_street"


def probe_set(n=32, count=3, along=0, planes=(-6.0, 6.0, 0.0), start=0.0, end=20.0):
    """(probe_levels, sky_levels, street, powers): box-filtered chains of the analytic street."""
    return ss.synthetic_probe_set(n, count, along, planes, start, end)
