"""``prefilter_sky_visibility`` filters in chunks of probes (one prefilter batch each): the result is
bit-identical to the whole-set filter (the code before chunking, re-derived here), and the bake's
memory estimate for ``--sky-visibility`` covers the writer's measured (tracemalloc) peak."""

import tracemalloc

import numpy as np

from envcap.capture.sky_sh import SH_C
from envcap.core import cube as cube_geometry
from envcap.core.lobes import LobeLadder
from envcap.core.rungs import rung_ladder
from envcap.formats.ktx2 import write_ktx2
from envcap.prefilter.fast import prefilter_many
from envcap.prefilter.sky_visibility import prefilter_sky_visibility, sh_basis, sky_visibility_chunk
from envcap.probeset.bake_bounds import estimate_bake


def _alpha(p, n, seed=0):
    rng = np.random.default_rng(seed)
    a = (rng.random((p, 6, n, n)) < 0.5).astype(np.float32)
    a[1] *= 0.3 + 0.7 * rng.random((6, n, n), dtype=np.float32)   # partial coverage: a batch's dynamic range differs
    return a


def test_chunks_are_bit_identical_to_the_whole_set(gl_ctx):
    n, p, order = 16, 5, 1
    lad = rung_ladder(n, "half_octave")
    bb = 2 * 6 * n * n * 16                       # chunks (and prefilter batches) of 2 probes: 2 + 2 + 1
    assert sky_visibility_chunk(n, bb) == 2
    alpha = _alpha(p, n)
    vis = prefilter_sky_visibility(alpha, lad, order, quality="default", ctx=gl_ctx, batch_bytes=bb)
    # the whole set in one call per rung, as before chunking
    a = alpha.astype(np.float64)
    basis = sh_basis(cube_geometry.texel_directions(n), order)
    chans = np.concatenate([np.repeat(a[..., None], 3, -1), a[..., None] * basis[None, ..., 1:]], -1)
    r_per, j0 = lad.per_level, vis.first_level
    assert j0 >= 1
    for r in range(r_per):
        powers = (lad.powers[0],) + tuple(lad.level_powers(j)[r] for j in range(1, lad.levels))
        chain = prefilter_many(chans, LobeLadder(lad.sizes, powers), ctx=gl_ctx, progress=False, batch_bytes=bb)
        for j in range(j0, lad.levels):
            want = np.concatenate([SH_C[0] * chain[j][..., :1], chain[j][..., 3:]], -1).astype(np.float32)
            np.testing.assert_array_equal(vis.levels[j - j0][r::r_per], want)


def test_estimate_covers_the_writers_peak(gl_ctx, tmp_path):
    n, p = 16, 12
    alpha = _alpha(p, n, 1)
    lad = rung_ladder(n, "half_octave")
    prefilter_sky_visibility(alpha[:1], lad, 1, ctx=gl_ctx)          # first-use allocations out of the count
    tracemalloc.start()
    try:
        vis = prefilter_sky_visibility(alpha, lad, 1, ctx=gl_ctx)
        write_ktx2(tmp_path / "v.ktx2", vis.packed_levels(), layered=True, fmt="rgba16f")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    extra = estimate_bake(p, n, writers=["sky_visibility"]).peak_bytes - estimate_bake(p, n).peak_bytes
    assert peak <= extra <= 3 * peak, (peak, extra)
