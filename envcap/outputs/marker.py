"""The marker that says "envcap wrote this directory": a small ``.envcap-output`` JSON file.

Every output directory envcap writes carries it at its top level::

    {"envcap_output": "probe-set", "envcap_version": "0.1.0"}

``envcap_output`` names the kind of output (``"probe-set"``, ``"prefilter-chain"``,
``"evaluation-report"``, ``"benchmark"``, or ``"output"`` for a library call that did not say).
envcap replaces an existing non-empty directory only when it carries this marker, or when the
user passes ``--force`` (``force=True``).

A single PNG that envcap writes outside such a directory (``envcap scenes --preview DIR``) carries
the same claim as a PNG text chunk ``Software: envcap`` (:data:`PNG_MARK`); envcap replaces an
existing file of that name only when it carries it (or with ``--force``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from PIL import Image

from envcap import __version__

MARKER_NAME = ".envcap-output"


def write_marker(directory: str | os.PathLike[str], kind: str) -> Path:
    """Write the marker of an output of ``kind`` into ``directory``; return the marker's path."""
    path = Path(directory) / MARKER_NAME
    path.write_text(json.dumps({"envcap_output": kind, "envcap_version": __version__}) + "\n")
    return path


def read_marker(directory: str | os.PathLike[str]) -> dict[str, str] | None:
    """The marker of ``directory`` as a dict, or ``None`` when it has none (or an unreadable one)."""
    try:
        doc = json.loads((Path(directory) / MARKER_NAME).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or not isinstance(doc.get("envcap_output"), str):
        return None
    return doc


def is_replaceable(directory: str | os.PathLike[str]) -> bool:
    """True when envcap may replace ``directory`` without ``--force``: it does not exist, is an
    empty directory, or carries the marker."""
    path = Path(directory)
    if not path.is_dir():
        return not path.exists()
    with os.scandir(path) as entries:
        if next(entries, None) is None:
            return True
    return read_marker(path) is not None


PNG_MARK = ("Software", "envcap")
"""The PNG text chunk (key, value) of a single PNG file envcap wrote."""


def png_marked(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a PNG whose text chunks carry :data:`PNG_MARK` (False for any other
    file, an unreadable one included)."""
    try:
        with Image.open(path) as img:
            return img.format == "PNG" and img.info.get(PNG_MARK[0]) == PNG_MARK[1]
    except (OSError, ValueError):
        return False
