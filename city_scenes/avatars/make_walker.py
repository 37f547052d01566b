"""Write walker.glb beside this file: envcap's skinned test avatar (envcap.dynamic.avatar_synthetic).

    PYTHONPATH=/path/to/envcap python3 city_scenes/avatars/make_walker.py

The bundled file is checked against the generator byte for byte (tests/dynamic/test_avatar_skin.py).
"""

from pathlib import Path

from envcap.dynamic.avatar_synthetic import write_walker

if __name__ == "__main__":
    out = Path(__file__).with_name("walker.glb")
    write_walker(out)
    print(f"wrote {out} ({out.stat().st_size} bytes)")
