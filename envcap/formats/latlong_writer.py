"""Probe-set writer ``latlong`` (opt-in: ``envcap capture --latlong``): lat-long OpenEXR maps of level 0,
for tools that take only lat-long environment maps (``docs/engines.md``).

* ``latlong/sky.exr``: the sky, RGB;
* ``latlong/probe_NNN.exr``: what probe ``NNN`` sees, RGB = street + (1 - alpha) sky (the
  premultiplied street composited over the sky, as the runtime does), so each file is a
  complete environment map; in the world's orientation, also for a probe of a street at an angle
  (whose cube has its faces along the street's frame).

Both ``2N x 4N`` pixels for ``N``-texel faces, OpenEXR's LatLong orientation
(:mod:`envcap.formats.latlong_exr`); half floats when every value fits, else float32 (a sun
splatted into the sky does not fit).  Manifest entries: ``files.latlong_sky``,
``files.latlong`` (one path per probe, in layer order).  Parameters: none.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from envcap.formats.latlong_exr import cube_to_latlong_seamless, write_latlong_exr
from envcap.formats.writer import FileEntries, ProbeSetWriter

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet


def write_latlong_maps(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the sky's and every probe's lat-long EXR under ``out_dir / "latlong"``."""
    (out_dir / "latlong").mkdir()
    sky = cube_to_latlong_seamless(np.asarray(ps.sky_levels[0])[..., :3])
    write_latlong_exr(out_dir / "latlong" / "sky.exr", sky)
    names = []
    yaws = {p.layer: st.frame_yaw_deg for st in ps.manifest.streets for p in st.probes}   # a probe's cube axes
    for i in range(ps.layer_count):
        street = cube_to_latlong_seamless(np.asarray(ps.levels[0][i]), yaw_deg=yaws.get(i, 0.0))
        rgb = street[..., :3] + (1.0 - np.clip(street[..., 3:4], 0.0, 1.0)) * sky
        name = f"latlong/probe_{i:03d}.exr"
        write_latlong_exr(out_dir / name, rgb)
        names.append(name)
    return {"latlong_sky": "latlong/sky.exr", "latlong": names}


WRITER = ProbeSetWriter("latlong", "lat-long OpenEXR maps of level 0: the sky and each probe over the sky",
                        write_latlong_maps, default=False)
