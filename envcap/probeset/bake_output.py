"""Bake a scene straight into a probe-set directory: ``envcap capture``'s job, also timed by
``envcap bench bake``.

Order: the output's temporary directory is made first (:func:`envcap.outputs.atomic_output_dir`),
then the bake (:func:`envcap.probeset.bake.bake_probe_set`) runs while the optional per-probe
files (``exr/``, ``previews/``) are written on worker threads as probes are captured
(:class:`envcap.formats.probe_files.ProbeFileWriter`); then the other writers (``ktx2``, and
any asked for) and the manifest (:func:`envcap.probeset.store.fill_probe_set_dir`); then the
directory is swapped in.  Any error leaves nothing.  The files are those of
``write_probe_set(out, bake_probe_set(...))`` with the same writers, byte for byte, except the
manifest's ``timings`` (tested).
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from envcap.formats.probe_files import ProbeFileWriter
from envcap.outputs import atomic_output_dir
from envcap.probeset.bake import bake_probe_set
from envcap.probeset.probe_set import ProbeSet, check_probe_set
from envcap.probeset.progress import BakeProgress
from envcap.probeset.store import fill_probe_set_dir
from envcap.scene.model import Scene

THREADED = ("exr", "previews")
"""Writers whose files :class:`~envcap.formats.probe_files.ProbeFileWriter` writes during the bake."""


def bake_to_directory(scene: Scene, out: str | os.PathLike[str], *, exr: bool = False, previews: bool = False,
                      writers: Iterable[str] = (), report: BakeProgress | None = None,
                      **bake_options: Any) -> tuple[Path, ProbeSet]:
    """Bake ``scene`` and write the probe set to ``out`` (a path or an
    :class:`envcap.outputs.OutputClaim`); return ``(path, probe set)``.

    ``exr`` / ``previews``: the per-probe files (written during the bake); ``writers``: more
    writers by name (the required ``ktx2`` always runs, e.g. ``["webgl2"]``; ``"exr"`` / ``"previews"`` here are
    the same as the flags); ``report``: stages and probes/s (stages ``sky``, ``capture``,
    ``prefilter``, ``write <writer>``, ``write files`` = waiting for the threads);
    ``bake_options``: passed to :func:`~envcap.probeset.bake.bake_probe_set`.  The manifest's
    ``timings.total_s`` is the whole call.
    """
    t0 = time.perf_counter()
    names = list(writers)
    exr = exr or "exr" in names
    previews = previews or "previews" in names
    rest = [n for n in names if n not in THREADED]
    report = BakeProgress("off") if report is None else report
    with atomic_output_dir(out, kind="probe-set") as tmp, \
            ProbeFileWriter(tmp, exr=exr, previews=previews) as files:
        ps = bake_probe_set(scene, report=report, on_captured=files.submit if files.active else None, writers=rest,
                            **bake_options)
        ps.manifest.to_json()  # strict JSON and every manifest rule
        check_probe_set(ps)
        written = {}
        if files.active:
            with report.stage("write files", ps.layer_count) as stage:
                written = files.finish(ps)   # waits for what the threads have not written yet
                stage.advance(ps.layer_count)
        ps.manifest = ps.manifest.with_timings(total_s=round(time.perf_counter() - t0, 3))
        fill_probe_set_dir(tmp, ps, rest, written=written, checked=True, report=report)
    return Path(out).resolve(), ps
