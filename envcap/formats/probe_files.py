"""The optional per-probe files (``exr/``, ``previews/``) written on worker threads while a bake
runs, fed probe by probe as they are captured.

The files are those of the ``exr`` and ``previews`` writers (:mod:`envcap.formats.exr_writer`,
:mod:`envcap.formats.preview_writer`), byte for byte: the same functions on the same level-0
arrays (a bake's level 0 is its capture, unchanged).  What the threads buy: OpenEXR's ZIP
compression and Pillow's PNG deflate run in C with the GIL released, numpy's tone mapping
largely too, so on 2 cores they overlap the bake's Python and GL work (measured in
``docs/bake.md``).  Probe arrays are copied when queued (the bake may reuse its buffers).

Use::

    with atomic_output_dir(out) as tmp, ProbeFileWriter(tmp, exr=True, previews=True) as files:
        ps = bake_probe_set(scene, on_captured=files.submit)
        entries = files.finish(ps)        # + the sky preview and the contact sheet; waits

Leaving the block without :meth:`ProbeFileWriter.finish` (an error) cancels what is queued and
waits for what runs, so nothing writes into a directory being removed.
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from envcap.formats.exr_writer import EXR_DIR, write_probe_exr
from envcap.formats.preview_writer import PREVIEW_DIR, write_probe_preview, write_set_previews
from envcap.formats.writer import FileEntries

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet

DEFAULT_THREADS = 2
"""Worker threads (the cores of the machine this was measured on; ``os.cpu_count()`` caps it)."""


class ProbeFileWriter:
    """Per-probe EXR cubes and preview crosses under ``out_dir``, written on ``threads`` worker
    threads as :meth:`submit` feeds them (see the module docstring).  ``exr`` / ``previews``:
    which files; with neither it does nothing."""

    def __init__(self, out_dir: str | os.PathLike[str], *, exr: bool, previews: bool,
                 threads: int = DEFAULT_THREADS) -> None:
        if threads < 1:
            raise ValueError(f"threads must be >= 1, got {threads}")
        self.out_dir = Path(out_dir)
        self.exr, self.previews = bool(exr), bool(previews)
        self.futures: dict[str, list[Future[str]]] = {"exr": [], "previews": []}
        self.layers = 0
        self.pool: ThreadPoolExecutor | None = None
        if self.exr or self.previews:
            if self.exr:
                (self.out_dir / EXR_DIR).mkdir()
            if self.previews:
                (self.out_dir / PREVIEW_DIR).mkdir()
            self.pool = ThreadPoolExecutor(max_workers=min(threads, os.cpu_count() or 1),
                                           thread_name_prefix="envcap-files")

    @property
    def active(self) -> bool:
        """Whether any file is asked for."""
        return self.pool is not None

    def submit(self, first_layer: int, rgba: NDArray, distance: NDArray | None) -> None:
        """Queue the files of layers ``first_layer ..``: ``rgba`` ``(P, 6, N, N, 4)`` level 0,
        ``distance`` ``(P, 6, N, N)`` (m) or ``None``.  Layers must come in order, without gaps."""
        if self.pool is None:
            return
        if first_layer != self.layers:
            raise ValueError(f"probe files: layer {first_layer} submitted, expected {self.layers}")
        rgba = np.array(rgba, copy=True)
        distance = None if distance is None else np.array(distance, copy=True)
        for j in range(rgba.shape[0]):
            layer = first_layer + j
            if self.exr:
                d = None if distance is None else distance[j]
                self.futures["exr"].append(self.pool.submit(write_probe_exr, self.out_dir, layer, rgba[j], d))
            if self.previews:
                self.futures["previews"].append(self.pool.submit(write_probe_preview, self.out_dir, layer, rgba[j]))
        self.layers += rgba.shape[0]

    def finish(self, ps: ProbeSet) -> FileEntries:
        """Queue the set's previews (sky, contact sheet), wait for every file; return their
        manifest entries (as the ``exr`` and ``previews`` writers would).  Re-raises the first
        error of a worker.  ``ps`` must hold exactly the layers submitted."""
        if self.pool is None:
            return {}
        if ps.layer_count != self.layers:
            raise ValueError(f"probe files: {self.layers} layers submitted, the probe set has {ps.layer_count}")
        last = self.pool.submit(write_set_previews, self.out_dir, ps) if self.previews else None
        try:
            entries: FileEntries = {key: [f.result() for f in fs] for key, fs in self.futures.items()
                                    if (key == "exr" and self.exr) or (key == "previews" and self.previews)}
            if last is not None:
                entries.update(last.result())
            return entries
        finally:
            self.close()

    def close(self) -> None:
        """Cancel what is queued and wait for what runs (idempotent)."""
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None

    def __enter__(self) -> "ProbeFileWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
