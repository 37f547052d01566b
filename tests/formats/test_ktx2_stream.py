"""``write_ktx2`` streams its levels (one converted level in memory at a time): the bytes it
writes are pinned to those of the earlier in-memory writer by their SHA-256, and a refused level
still leaves no file."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from envcap import __version__
from envcap.formats.ktx2 import read_ktx2, write_ktx2

PINNED_VERSION = "0.1.0"
"""envcap's version when the hashes were taken: ``KTXwriter = "envcap <version>"`` is in the file."""

PINNED = {
    # (layers, face size, fmt, seed) -> sha256 of the file written by the in-memory writer (before streaming).
    # Re-pinned when the custom key left the files (issue 19, one container writer): these are the hashes
    # the earlier streaming writer gave for the same levels without its ``kv`` entry, checked then.
    (3, 16, "rgba16f", 1): "a2f7ae0dc612a3ab073e7323aa4099fad8f168693940d781ae41e72a71718182",
    (0, 8, "rgba32f", 2): "5c501d7f9f86f16861ddc8d88d7fa6038f8ca7bddc90db15c027a35b91d58a4d",
}


def _levels(layers: int, n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out, k = [], 0
    while True:
        m = max(1, n >> k)
        out.append((rng.random(((layers,) if layers else ()) + (6, m, m, 4)) * 100).astype(np.float32))
        if m == 1:
            return out
        k += 1


@pytest.mark.parametrize("key", list(PINNED))
def test_streamed_file_is_bit_identical_to_the_in_memory_writer(tmp_path, key):
    assert __version__ == PINNED_VERSION, "version changed: re-pin after checking only KTXwriter moved"
    layers, n, fmt, seed = key
    levels = _levels(layers, n, seed)
    path = write_ktx2(tmp_path / "t.ktx2", levels, layered=bool(layers), fmt=fmt, premultiplied=bool(layers))
    assert hashlib.sha256(path.read_bytes()).hexdigest() == PINNED[key]
    back, _ = read_ktx2(path)
    dtype = np.float16 if fmt == "rgba16f" else np.float32
    for a, b in zip(levels, back):
        np.testing.assert_array_equal(b, a.astype(dtype).astype(np.float32))


def test_streamed_blocks_and_errors(tmp_path, monkeypatch):
    """Levels larger than one conversion block are written block by block to the same bytes; a bad
    texel in the largest level (written last) is refused with the whole level's count, no file left."""
    import envcap.formats.ktx2 as ktx2

    levels = _levels(2, 8, 3)
    whole = write_ktx2(tmp_path / "whole.ktx2", levels, layered=True).read_bytes()
    monkeypatch.setattr(ktx2, "_BLOCK", 7)   # blocks that cut texels and layers
    assert write_ktx2(tmp_path / "blocks.ktx2", levels, layered=True).read_bytes() == whole
    levels[0][1, 2, 3, 4, 0] = np.nan
    levels[0][0, 0, 0, 0, 1] = np.inf
    with pytest.raises(ValueError, match="level 0: 2 value"):
        write_ktx2(tmp_path / "bad.ktx2", levels, layered=True)
    levels[0][1, 2, 3, 4, 0] = levels[0][0, 0, 0, 0, 1] = 7e4
    with pytest.raises(ValueError, match="level 0: 2 value.*half-float maximum"):
        write_ktx2(tmp_path / "bad.ktx2", levels, layered=True)
    clamped, _ = read_ktx2(write_ktx2(tmp_path / "clamped.ktx2", levels, layered=True, clamp=True))
    assert clamped[0][1, 2, 3, 4, 0] == 65504.0
    assert not (tmp_path / "bad.ktx2").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocks.ktx2", "clamped.ktx2", "whole.ktx2"]
