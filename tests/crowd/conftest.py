"""Fixtures of the crowd tests: the session's small canyon probe set written to a directory, as
``envcap capture canyon --out DIR`` writes one (the session bake of tests/conftest.py, ~1 s)."""

import pytest


@pytest.fixture(scope="session")
def canyon_probe_dir(canyon_probe_set, tmp_path_factory):
    from envcap.probeset.store import write_probe_set

    path = tmp_path_factory.mktemp("crowd") / "canyon_probes"
    write_probe_set(path, canyon_probe_set)
    return path
