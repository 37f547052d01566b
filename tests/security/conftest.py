"""Fixtures of the security tests: a small probe set with its WebGL2 face atlas, written once per
session (the session's canyon bake), that each test copies next to a secret file of its own."""

import pytest

from envcap.probeset.store import write_probe_set


@pytest.fixture(scope="session")
def web_probe_dir(canyon_probe_set, tmp_path_factory):
    """``canyon_probe_set`` (6 probes, 8^2 faces) written with ``probes.ktx2``, ``sky.ktx2`` and
    ``probes_atlas.ktx2``.  Shared: copy it before changing anything."""
    return write_probe_set(tmp_path_factory.mktemp("security") / "canyon", canyon_probe_set, exr=False,
                           previews=False, writers=["ktx2", "webgl2"])
