"""Import memory (issue 10: at most 200 bytes per triangle at peak).  Memory, unlike time, is a
property of the code: the peak of traced allocations (numpy's included) is deterministic."""

import json
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from envcap.scene.city_files import write_city
from envcap.scene.city_layout import CitySpec, generate_city_layout
from envcap.scene.mesh_import import import_meshes
from envcap.scene.mesh_parts import vertex_ids


@pytest.mark.parametrize("through", ["ply_files", "mitsuba_xml"])
def test_import_peak_memory_is_under_200_bytes_per_triangle(tmp_path: Path, through: str) -> None:
    truth = write_city(generate_city_layout(CitySpec(facade_cells=6)), tmp_path / "city")
    files = sorted((tmp_path / "city" / "buildings").glob("*.ply")) if through == "ply_files" \
        else [tmp_path / "city" / "city.xml"]
    import trimesh  # noqa: F401  (its import is not the import's memory)
    tracemalloc.start()
    try:
        mesh, report = import_meshes(files, up_axis="z", offset=truth["frame"]["offset"])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert mesh.triangle_count > 40_000 and report.flipped == len(truth["inward_files"])
    # a textured scene also holds its texture coordinates (36 B per triangle) and its images
    extra = mesh.uv_layer.nbytes + mesh.textures.nbytes if mesh.textured else 0
    assert mesh.textured == (through == "mitsuba_xml")
    assert (peak - extra) / mesh.triangle_count <= 200, f"{(peak - extra) / mesh.triangle_count:.0f} bytes per triangle"


def test_vertex_ids_join_equal_positions_only() -> None:
    pts = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0 + 1e-12], [0.0, 0.0, 0.0], [-0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    ids = vertex_ids(pts)
    assert ids[0] == ids[4] and ids[2] == ids[3]                  # -0.0 == 0.0 as numbers
    assert len({ids[0], ids[1], ids[2]}) == 3
