"""The street map's size check: a grid past ``MAX_MAP_SIZE`` texels per side (the texture limit of
most GPUs) is refused before anything is allocated, with one line naming ``--map-cell``, the size
it would need and the smallest cell that fits (which then does fit)."""

import pytest

from envcap.probeset.manifest import Street
from envcap.probeset.planes import Planes
from envcap.runtime.street_map import MAX_MAP_SIZE, street_map


def street(length, lo=-1.0, hi=1.0):
    return Street(name="s", axis="x", start=0.0, end=length, center=0.5 * (lo + hi),
                  planes=Planes(facade_min=lo, facade_max=hi, ground=0.0), probes=())


def test_600_m_street_at_1_cm_is_refused_naming_the_option_and_a_cell_that_fits():
    with pytest.raises(ValueError) as err:
        street_map((street(600.0),), 0.01)
    msg = str(err.value)
    assert "\n" not in msg and "--map-cell" in msg and "60000 x" in msg and str(MAX_MAP_SIZE) in msg
    fit = float(msg.rsplit("at least ", 1)[1].split(" m")[0])
    assert 600.0 / MAX_MAP_SIZE < fit < 1.01 * 600.0 / (MAX_MAP_SIZE - 1)
    m = street_map((street(600.0),), fit)              # the advised cell fits
    assert max(m.size) <= MAX_MAP_SIZE


@pytest.mark.parametrize("cell", [1e-9, 5e-324])
def test_tiny_cells_fail_with_the_size_error_not_memory_or_overflow(cell):
    with pytest.raises(ValueError, match="--map-cell"):
        street_map((street(600.0),), cell)


def test_limit_is_inclusive_and_explicit_sizes_are_checked():
    assert street_map((street(float(MAX_MAP_SIZE), -0.5, 0.5),), 1.0).size[0] == MAX_MAP_SIZE
    with pytest.raises(ValueError, match=f"{MAX_MAP_SIZE + 1} x"):
        street_map((street(float(MAX_MAP_SIZE) + 1.0, -0.5, 0.5),), 1.0)
    with pytest.raises(ValueError, match="20000 x 4"):
        street_map((street(10.0),), 1.0, origin=(0.0, -2.0), size=(20000, 4))
