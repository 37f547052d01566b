"""The probe-set output writers, by name (see :mod:`envcap.formats.writer`).

Adding a writer: one module that defines ``WRITER = ProbeSetWriter(...)`` (name, summary,
write function; its docstring lists its files, manifest entries and parameters) and one
``register_writer`` line below.  A program or a test can register its own at run time with
:func:`register_writer`.  Registry order is the order the writers run and their entries appear
in the manifest's ``files``.
"""

from __future__ import annotations

from collections.abc import Iterable

from envcap.formats import (exr_writer, inverse_distance_writer, ktx2_writer, latlong_hdr_writer, latlong_writer,
                            preview_writer, sky_visibility_writer, webgl2_writer)
from envcap.formats.writer import ProbeSetWriter

WRITERS: dict[str, ProbeSetWriter] = {}
"""Registered writers by name, in registration order."""


def register_writer(writer: ProbeSetWriter) -> ProbeSetWriter:
    """Add ``writer`` (``ValueError`` if its name is taken); return it."""
    if writer.name in WRITERS:
        raise ValueError(f"a probe-set writer named {writer.name!r} is already registered")
    WRITERS[writer.name] = writer
    return writer


def unregister_writer(name: str) -> None:
    """Remove the writer ``name`` (``KeyError`` if there is none)."""
    del WRITERS[name]


def default_writer_names() -> list[str]:
    """The writers written when the caller does not choose (``default=True``), in order."""
    return [w.name for w in WRITERS.values() if w.default or w.required]


def select_writers(names: Iterable[str]) -> list[ProbeSetWriter]:
    """The writers ``names`` plus the required ones, in registry order (``ValueError`` for an
    unknown name)."""
    wanted = set(names)
    unknown = sorted(wanted - set(WRITERS))
    if unknown:
        raise ValueError(f"unknown probe-set writer(s) {unknown}; registered: {list(WRITERS)}")
    return [w for w in WRITERS.values() if w.required or w.name in wanted]


register_writer(ktx2_writer.WRITER)
register_writer(exr_writer.WRITER)
register_writer(preview_writer.WRITER)
register_writer(webgl2_writer.WRITER)
register_writer(latlong_writer.WRITER)
register_writer(latlong_hdr_writer.WRITER)
register_writer(sky_visibility_writer.WRITER)
register_writer(inverse_distance_writer.WRITER)
