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

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from envcap.formats.latlong_exr import cube_to_latlong_seamless, write_latlong_exr
from envcap.formats.writer import FileEntries, ProbeSetWriter

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet


def latlong_maps(ps: ProbeSet) -> Iterator[tuple[str, NDArray[np.float32]]]:
    """The set's lat-long maps of level 0, ``(stem, (2N, 4N, 3) RGB)``: ``"sky"``, then
    ``"probe_NNN"`` per layer (street + (1 - alpha) sky, in the world's orientation)."""
    sky = cube_to_latlong_seamless(np.asarray(ps.sky_levels[0])[..., :3])
    yield "sky", sky
    yaws = {p.layer: st.frame_yaw_deg for st in ps.manifest.streets for p in st.probes}   # a probe's cube axes
    for i in range(ps.layer_count):
        street = cube_to_latlong_seamless(np.asarray(ps.levels[0][i]), yaw_deg=yaws.get(i, 0.0))
        yield f"probe_{i:03d}", (street[..., :3] + (1.0 - np.clip(street[..., 3:4], 0.0, 1.0)) * sky).astype(np.float32)


def write_latlong_maps(out_dir: Path, ps: ProbeSet) -> FileEntries:
    """Write the sky's and every probe's lat-long EXR under ``out_dir / "latlong"``."""
    (out_dir / "latlong").mkdir(exist_ok=True)
    names = []
    for stem, rgb in latlong_maps(ps):
        write_latlong_exr(out_dir / "latlong" / f"{stem}.exr", rgb)
        names.append(f"latlong/{stem}.exr")
    return {"latlong_sky": names[0], "latlong": names[1:]}


WRITER = ProbeSetWriter("latlong", "lat-long OpenEXR maps of level 0: the sky and each probe over the sky",
                        write_latlong_maps, default=False)
