"""What a probe-set output writer is: a name, a summary and a function that writes files.

A writer turns a checked :class:`envcap.probeset.probe_set.ProbeSet` into files of the
probe-set directory and returns their manifest ``files`` entries.  Writers are listed in
:mod:`envcap.formats.registry`; :func:`envcap.probeset.store.write_probe_set` runs the ones
asked for, in registry order, inside one atomic output directory (any error leaves nothing).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Union

if TYPE_CHECKING:  # the writers' input type; formats does not depend on probeset at run time
    from envcap.probeset.probe_set import ProbeSet

MANIFEST_FILE = "manifest.json"
"""The manifest of a probe-set directory: written by the store after the writers, never by them."""

FileEntries = dict[str, Union[str, list[str]]]
"""Manifest ``files`` entries: key -> path, or list of paths, relative to the directory."""

WriteFn = Callable[[Path, "ProbeSet"], FileEntries]
"""``write(out_dir, probe_set)``: write under ``out_dir`` (a temporary directory that becomes the
probe-set directory when every writer succeeded) and return the files' entries."""


@dataclass(frozen=True)
class ProbeSetWriter:
    """A probe-set output writer.

    ``name``: the registry key (also what ``write_probe_set(writers=...)`` asks for);
    ``summary``: one line for help texts; ``write``: see :data:`WriteFn`; ``default``: written
    unless the caller leaves it out; ``required``: always written (the reader needs its files).
    """

    name: str
    summary: str
    write: WriteFn
    default: bool = True
    required: bool = False
