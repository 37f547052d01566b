"""The Funk-Hecke filter of visibility moments (envcap.prefilter.visibility_harmonics) against
independent references: its SH rows against wide_lobes.real_sh, the multiplication operators and
the mirror signs as pointwise identities at random directions, the orbits as a partition of the
texels, and V = filter(alpha Y_c) against the float64 brute-force convolution
(envcap.prefilter.exact.convolve_exact) for hard-edged and noisy alpha, odd face sizes, orders 1-2,
lobes from w = 1 to w = 126, one chunk or many."""

import numpy as np
import pytest

from envcap.core import cube as cube_geometry
from envcap.prefilter import visibility_harmonics as vh
from envcap.prefilter.exact import convolve_exact
from envcap.prefilter.sky_visibility import sh_basis
from envcap.prefilter.wide_lobes import real_sh


def _dirs(count, seed=0):
    u = np.random.default_rng(seed).normal(size=(count, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def _canyon_alpha(n, p=2):
    d = cube_geometry.texel_directions(n)
    a = (((np.abs(d[..., 0]) > 0.45) & (d[..., 1] < 0.5)) | (d[..., 1] < -0.1)).astype(np.float32)
    out = np.stack([a, np.roll(a, 3, axis=2)][:p])
    out[-1, 2] *= 0.5                                      # partial coverage on one face
    return out


def test_sh_rows_match_the_reference_recurrence():
    d = _dirs(300)
    np.testing.assert_allclose(vh.real_sh_rows(d, 30), real_sh(d, 30), rtol=0, atol=1e-12)


def test_multiplication_operators_are_pointwise_identities():
    big = 24
    u = _dirs(400, 1)
    y = vh.real_sh_rows(u, big)
    c = np.random.default_rng(2).normal(size=(big + 1) ** 2)
    c[(big - 1) ** 2:] = 0.0                               # f of degree big - 2: x f has degree big - 1
    for axis, op in enumerate(vh.multiplication_operators(big)):
        got = op.apply(c) @ y[:big * big]
        np.testing.assert_allclose(got, u[:, axis] * (c @ y), atol=1e-12)


def test_mirror_signs_are_the_reflections_of_the_harmonics():
    u = _dirs(200, 3)
    y = vh.real_sh_rows(u, 20)
    for axis in range(3):
        flipped = u.copy()
        flipped[:, axis] *= -1.0
        np.testing.assert_allclose(vh.real_sh_rows(flipped, 20), vh.mirror_signs(axis, 20)[:, None] * y, atol=1e-12)


@pytest.mark.parametrize("n", [1, 3, 8, 15])
def test_orbits_cover_every_texel_once(n):
    cover = np.zeros(6 * n * n)
    d_all = cube_geometry.texel_directions(n).reshape(-1, 3)
    for d, idx, inv_stab in vh._orbits(n):
        np.add.at(cover, idx.reshape(-1), np.broadcast_to(inv_stab, idx.shape).reshape(-1))
        for g in range(8):                                 # each image is the flipped direction
            flip = np.array([-1.0 if g & 4 else 1.0, -1.0 if g & 2 else 1.0, -1.0 if g & 1 else 1.0])
            np.testing.assert_allclose(d_all[idx[g]], d * flip, atol=1e-12)
    np.testing.assert_allclose(cover, 1.0)


def _check(alpha, powers, sizes, order, atol):
    out = vh.harmonic_visibility(alpha, powers, sizes, order, lambda u: sh_basis(u, order))
    basis = sh_basis(cube_geometry.texel_directions(alpha.shape[2]), order)
    worst = 0.0
    for i, (w, s) in enumerate(zip(powers, sizes)):
        for p in range(alpha.shape[0]):
            ref = convolve_exact(alpha[p].astype(np.float64)[..., None] * basis, w, s)
            worst = max(worst, float(np.abs(out[i][p] - ref).max()))
    assert worst < atol, worst
    return out


def test_matches_the_exact_convolution_from_wide_to_narrow_lobes():
    # the stored rungs of a 32^2 capture's half-octave ladder and a narrow one on its own faces
    _check(_canyon_alpha(32), [126.0, 43.25, 30.0, 9.31, 6.0, 1.0], [16, 16, 16, 16, 8, 8], 1, 2e-5)


def test_matches_the_exact_convolution_for_noise_and_order_2():
    noise = np.random.default_rng(4).random((2, 6, 16, 16)).astype(np.float32)   # a flat spectrum: the hardest input
    _check(noise, [62.0, 14.0, 1.0], [8, 8, 8], 2, 5e-5)


def test_odd_faces_and_the_clamped_cosine_kink():
    # odd faces: texels on the mirror planes are their own images (orbits of 4 or 2); a 3^2 output's
    # centre is a face normal, and a 15^2 input's middle rows lie on its w = 1 lobe's horizon, where
    # the truncated series of max(0, t) converges slowest (docs/lobes.md): a looser bound there
    _check(_canyon_alpha(15), [30.0, 6.0], [7, 7], 1, 2e-5)
    _check(_canyon_alpha(15), [1.0], [3], 1, 1e-3)


def test_chunks_give_the_same_moments(monkeypatch):
    alpha = _canyon_alpha(16, 2)
    whole = vh.harmonic_visibility(alpha, [20.0, 3.0], [8, 8], 1, lambda u: sh_basis(u, 1))
    monkeypatch.setattr(vh, "CHUNK_BYTES", 1)                  # one probe per chunk
    parts = vh.harmonic_visibility(alpha, [20.0, 3.0], [8, 8], 1, lambda u: sh_basis(u, 1))
    for a, b in zip(whole, parts):
        np.testing.assert_allclose(a, b, atol=1e-6)


def test_degree_plan_and_its_limit():
    big, limits = vh.degree_plan([126.0, 43.25, 6.0, 1.0])
    assert limits[0] == big == vh.band_limit(126.0) and limits[1] < big
    assert limits[3] == min(vh.band_limit(1.0), max(vh.FLOOR_DEGREE, big))   # w <= 16: the projection's bands
    with pytest.raises(ValueError, match="SH degree"):
        vh.degree_plan([5000.0])
