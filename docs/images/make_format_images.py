"""Regenerate docs/images/format_*.png: previews of a real probe set (envcap.formats.png_preview).

Bakes two probes of the bundled canyon at 64^2 (sun splatted into the sky, so the sky cross
shows it) and writes the probe cross, a contact sheet and the sky cross.
Run: python3 docs/images/make_format_images.py
"""

from pathlib import Path

from envcap.probeset.bake import bake_probe_set
from envcap.formats.png_preview import contact_sheet_png, cube_cross_png
from envcap.scene import load_scene

HERE = Path(__file__).resolve().parent


def main() -> None:
    scene = load_scene("canyon")
    ps = bake_probe_set(scene, resolution=64, spacing=300.0, sun_in_sky=True, filter_levels=False, progress=False)
    probes = ps.levels[0]
    cube_cross_png(HERE / "format_probe_cross.png", probes[0])
    contact_sheet_png(HERE / "format_contact_sheet.png", list(probes), [f"probe {i}" for i in range(len(probes))])
    cube_cross_png(HERE / "format_sky_cross.png", ps.sky_levels[0])
    for name in ("format_probe_cross", "format_contact_sheet", "format_sky_cross"):
        print(HERE / f"{name}.png")


if __name__ == "__main__":
    main()
