"""The numpy twin's textures are checked when built (issue 9, silent wrong answers): a NaN or Inf
texel in a probe chain or the sky chain is a one-line ValueError naming the level and the layer.
Old: the lookup returned NaN radiance, silently (the GLSL cannot raise, so the check is here and
in read_probe_set)."""

import numpy as np
import pytest

from envcap.runtime import synthetic_street as ss
from envcap.runtime.chains import ProbeChains, SkyChain
from envcap.runtime.sampling import sample_street


@pytest.fixture(scope="module")
def chains():
    return ss.synthetic_probe_set(4, count=3)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_a_nonfinite_probe_texel_names_level_and_layer(chains, value):
    probes, _, _, powers = chains
    bad = [a.copy() for a in probes]
    bad[1][2, 3, 0, 1, 0] = value
    bad[1][2, 4, 1, 1, 2] = value
    with pytest.raises(ValueError, match=r"^probe chain level 1, layer 2: 2 of \d+ texel values are NaN/Inf") as e:
        ProbeChains(bad, powers)
    assert "\n" not in str(e.value)


def test_a_nonfinite_sky_texel_names_the_level_and_fails_before_any_lookup(chains):
    probes, sky, street, powers = chains
    bad = [a.copy() for a in sky]
    bad[2][...] = np.nan
    with pytest.raises(ValueError, match=r"^sky chain level 2: \d+ of \d+ texel values are NaN/Inf"):
        SkyChain(bad)
    with pytest.raises(ValueError, match="sky chain level 2"):
        sample_street(ProbeChains(probes, powers), bad, street, [5.0, 1.6, 0.0], [0.0, 0.0, 1.0], 1.0)


def test_finite_chains_sample_the_same_through_a_sky_chain(chains):
    """Huge but finite radiance is accepted; a SkyChain and its raw levels give the same lookup."""
    probes, sky, street, powers = chains
    big = [a.copy() for a in sky]
    big[0][2, 0, 0, :3] = 3.0e38
    pc = ProbeChains(probes, powers)
    x = np.array([[5.0, 1.6, 0.0], [12.0, 3.0, -2.0]])
    d = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    a = sample_street(pc, sky, street, x, d, 4.0)
    b = sample_street(pc, SkyChain(sky), street, x, d, 4.0)
    assert np.array_equal(a, b) and np.all(np.isfinite(a))
    SkyChain(big)
