"""A tiny city baked once per session: the bundled ``crossing`` (two streets) at 6 x 8^2 texels
every 100 m, one shard per street, in this process (~1 s)."""

import pytest
from city_fixtures import SETTINGS


@pytest.fixture(scope="session")
def crossing_city(gl_ctx, tmp_path_factory):
    """The city directory (read it, do not modify it)."""
    from envcap.city.bake import bake_city
    from envcap.city.plan import BakeSettings

    out = tmp_path_factory.mktemp("city") / "crossing"
    bake_city("crossing", out, BakeSettings(**SETTINGS), budget_mb=0, ctx=gl_ctx)
    return out

