"""The avatar part of ``envcap bench dynamic_street --avatars also|only``: walkers posed around
crowd positions, fresh captures with their meshes as truth, the probes without and with the
dynamic terms of the avatars' proxy spheres (:mod:`envcap.evaluate.dynamic_avatars`).

Writes ``dynamic_street_avatars.json`` (rows, crowds, positions), ``dynamic_street_avatars.md``
(per crowd x material, and per material over the crowds hiding >= 10 % of the visible sky) and
``dynamic_street_avatars.png`` (error against visible sky hidden).  A helper module, not a
benchmark of its own (no ``add_arguments``).
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any


from envcap.benchmarks.dynamic_street_plot import plot_error_vs_hidden
from envcap.evaluate.dynamic_avatars import (
    DEFAULT_CROWDS,
    crowd_table,
    evaluate_avatar_crowds,
    material_summary,
)
from envcap.evaluate.predict import Predictor
from envcap.evaluate.sweep import street_extent

AVATAR_POINT_HEIGHT_M = 1.0
"""Height of the shading points among the avatars (m above the ground under them: a shoulder among
children, a hip among adults; the walker is 1.9 m tall)."""


def avatar_points(manifest: Any, street: str, positions: Sequence[Sequence[float]]) -> list[list[float]]:
    """``positions`` (world m) with their height replaced by :data:`AVATAR_POINT_HEIGHT_M` above the
    ground under each on ``street`` of the probe-set ``manifest``
    (:meth:`envcap.evaluate.sweep.StreetExtent.ground_under`: on a street that follows the terrain,
    the nearest probe's ground plane with its slope)."""
    extent = street_extent(manifest, street)
    return [[float(p[0]), extent.ground_under(p) + AVATAR_POINT_HEIGHT_M, float(p[2])] for p in positions]


def avatar_section(scene: Any, predictor: Predictor, street: str, positions: Sequence[Sequence[float]], *, ctx: Any,
                   resolution: int, models: Sequence[str]) -> dict[str, Any]:
    """``{"result": JSON-able dict, "md": Markdown}`` of the avatar evaluation at ``positions``
    (their height replaced by :func:`avatar_points`)."""
    t0 = time.perf_counter()
    pts = avatar_points(predictor.manifest, street, positions)
    rows = evaluate_avatar_crowds(scene, predictor, street, pts, crowds=DEFAULT_CROWDS, ctx=ctx,
                                  resolution=resolution, models=models)
    variants = [f"{s}{'' if m is None else '+' + m}" for s in ("static", "oracle") for m in [None, *models]]
    md = ("## Avatars: error per crowd and material (RMS over positions of relative errors, %)\n\n"
          + crowd_table(rows, variants)
          + "\n## Avatars: error per material (RMS over positions x crowds, %)\n\n" + material_summary(rows, variants))
    result = {"positions": pts, "crowds": [c.label for c in DEFAULT_CROWDS], "resolution": resolution,
              "models": list(models), "rows": rows, "total_s": time.perf_counter() - t0}
    return {"result": result, "md": md}


def write_avatar_files(out: Path, section: dict[str, Any]) -> None:
    """The section's JSON, Markdown and PNG into the directory ``out`` (being written by the caller)."""
    (out / "dynamic_street_avatars.json").write_text(json.dumps(section["result"], indent=1))
    (out / "dynamic_street_avatars.md").write_text(section["md"])
    plot_avatars(section["result"]["rows"], section["result"]["models"], out / "dynamic_street_avatars.png")


def plot_avatars(rows: Sequence[dict[str, Any]], models: Sequence[str], path: Path) -> None:
    """Error (%) against visible sky hidden (%), one panel per static source, one colour per variant."""
    plot_error_vs_hidden(rows, models, path, "avatars", "canyon: walkers (skinned, posed) around a point; truth = fresh "
                         "capture with the meshes, prediction = their proxy spheres (3 materials)")
