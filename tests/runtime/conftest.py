"""Fixtures of the runtime tests: the synthetic street's chains uploaded as GL textures."""

import pytest

from envcap.gpu.cube_array import CubeArrayTexture, cube_texture

from runtime_fixtures import probe_set


@pytest.fixture(scope="module")
def scene(gl_ctx):
    """``(probe_levels, sky_levels, street, powers, probe texture, sky texture)`` of the default
    synthetic street (``runtime_fixtures.probe_set()``), uploaded once per module."""
    probes, sky, street, powers = probe_set()
    pt = CubeArrayTexture(probes)
    st = cube_texture(gl_ctx, sky)
    yield probes, sky, street, powers, pt, st
    pt.release()
    st.release()
