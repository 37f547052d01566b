"""Fixtures of the crowd tests: the session's small canyon probe set written to a directory, as
``envcap capture canyon --out DIR`` writes one (the session bake of tests/conftest.py, ~1 s)."""

import pytest


@pytest.fixture(scope="session")
def canyon_probe_dir(canyon_probe_set, tmp_path_factory):
    from envcap.probeset.store import write_probe_set

    path = tmp_path_factory.mktemp("crowd") / "canyon_probes"
    write_probe_set(path, canyon_probe_set)
    return path


@pytest.fixture(scope="session")
def canyon_distance_dir(canyon_probe_set, tmp_path_factory):
    """The session canyon set with ``inverse_distance.ktx2`` (as ``envcap capture`` writes it by
    default), without EXRs: the crowd's default lookup there is ``depth_refine``."""
    from envcap.probeset.store import write_probe_set

    path = tmp_path_factory.mktemp("crowd") / "canyon_distance"
    write_probe_set(path, canyon_probe_set, writers=["inverse_distance"])
    return path
