"""The placement rules of envcap.placement.partition against independent references: the exact
programme against brute force over every subset, the quantile rule against a numerically
integrated cumulative (docs/placement.md)."""

import itertools

import numpy as np
import pytest

from envcap.placement.partition import best_subset, density_positions, served_error


def brute_force(s, x, e, count):
    """Least mean error over every subset, each point served by its nearest probe (ties: lower index)."""
    best = np.inf
    for sub in itertools.combinations(range(len(s)), count):
        d = np.abs(np.asarray(x)[:, None] - np.asarray(s)[list(sub)][None, :])
        k = np.array(sub)[np.argmin(d, axis=1)]
        best = min(best, float(np.mean(e[k, np.arange(len(x))])))
    return best


@pytest.mark.parametrize("seed", range(40))
def test_best_subset_is_the_brute_force_optimum(seed):
    rng = np.random.default_rng(seed)
    k, j = int(rng.integers(1, 8)), int(rng.integers(1, 14))
    s = np.sort(rng.choice(np.arange(0.0, 30.0, 0.5), k, replace=False))
    x = rng.uniform(-3, 33, j)
    if seed % 3 == 0:   # points exactly on candidates and on midpoints: the ties
        x = np.round(x * 4) / 4
    e = rng.uniform(0, 1, (k, j))
    if seed % 4 == 0:   # candidates that cannot serve some points
        e[rng.uniform(size=e.shape) < 0.25] = np.inf
    for n in range(1, k + 1):
        chosen, mean = best_subset(s, x, e, n)
        assert len(chosen) == n and np.all(np.diff(chosen) > 0)
        ref = brute_force(s, x, e, n)
        if np.isinf(ref):
            assert np.isinf(mean)
        else:
            assert mean == pytest.approx(ref, rel=1e-12, abs=1e-15)
            assert served_error(chosen, s, x, e) == pytest.approx(mean, rel=1e-12, abs=1e-15)


def test_best_subset_refuses_what_it_cannot_do():
    s, x, e = np.array([0.0, 1.0]), np.array([0.5]), np.ones((2, 1))
    for n in (0, 3):
        with pytest.raises(ValueError, match="count"):
            best_subset(s, x, e, n)
    with pytest.raises(ValueError, match="increasing"):
        best_subset(np.array([1.0, 0.0]), x, e, 1)
    with pytest.raises(ValueError, match=">= 0"):
        best_subset(s, x, -e, 1)


def test_a_uniform_density_gives_the_uniform_placement_exactly():
    for a, b, n in ((-30.0, 30.0, 6), (0.0, 7.0, 1), (2.5, 3.0, 13)):
        got = density_positions(np.linspace(a, b, 17), np.full(16, 0.3), n)
        np.testing.assert_allclose(got, a + (np.arange(n) + 0.5) * (b - a) / n, rtol=0, atol=1e-12)


def test_positions_sit_at_the_quantiles_of_the_density():
    rng = np.random.default_rng(7)
    edges = np.sort(rng.uniform(0, 50, 21))
    rho = rng.uniform(0, 2, 20)
    rho[5] = 0.0                      # an empty cell
    n = 9
    got = density_positions(edges, rho, n)
    # independent: the cumulative integrated on a fine grid, then read off at the positions
    fine = np.linspace(edges[0], edges[-1], 200_001)
    dens = rho[np.clip(np.searchsorted(edges, fine, side="right") - 1, 0, 19)]
    cum = np.concatenate([[0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(fine))])
    np.testing.assert_allclose(np.interp(got, fine, cum) / cum[-1], (np.arange(n) + 0.5) / n, atol=2e-4)
    assert np.all(np.diff(got) > 0) and edges[0] <= got[0] and got[-1] <= edges[-1]
    # denser where the density is higher: more probes per meter in the denser half
    dense = rho > np.median(rho)
    share = [np.sum([(edges[c] <= p < edges[c + 1]) for c in np.flatnonzero(m) for p in got]) /
             np.sum(np.diff(edges)[m]) for m in (dense, ~dense)]
    assert share[0] > share[1]


def test_density_positions_refuse_bad_input():
    for edges, rho in (([0, 1], [0.0]), ([0, 1], [np.nan]), ([1, 0], [1.0]), ([0, 1, 2], [1.0])):
        with pytest.raises(ValueError):
            density_positions(edges, rho, 2)
    with pytest.raises(ValueError, match="count"):
        density_positions([0, 1], [1.0], 0)
