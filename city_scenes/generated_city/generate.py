"""Regenerate the bundled generated city into ``data/`` beside this file (delete ``data/`` first).

The city is envcap's procedural "OSM-like" test city (``envcap.scene.city_layout``: a grid district
turned 7 deg and an irregular district of six streets on a 6 % slope; ``envcap.scene.city_files``:
one Z-up PLY per building in projected coordinates, some wound inward, a Mitsuba 3 XML with
materials, a textured glTF and an OBJ + MTL building, terrain, and ``truth.json``).
Run: ``python3 city_scenes/generated_city/generate.py`` from the repository root.
"""

from pathlib import Path

from envcap.scene.city_files import write_city
from envcap.scene.city_layout import CitySpec, generate_city_layout

if __name__ == "__main__":
    out = Path(__file__).resolve().parent / "data"
    truth = write_city(generate_city_layout(CitySpec()), out)
    print(f"wrote {out}: {truth['buildings']} buildings, {truth['building_triangles']} + {truth['terrain_triangles']} triangles")
