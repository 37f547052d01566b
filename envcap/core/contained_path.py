"""Paths that an untrusted file names, kept inside the folder that file describes.

A probe set is downloaded and shared: its ``manifest.json`` (and a city's ``city.json``) is
untrusted input, and a name it gives (``files.sky``, a shard's ``path``, ...) must never lead a
reader, the viewer's server or ``envcap export web`` to a file outside the set.  Two checks, one
rule:

* :func:`name_problem`: the name alone (what the manifest readers check, before any file is
  touched): a non-empty relative ``/``-separated path without ``..``, without a NUL or a
  backslash, not absolute in POSIX or Windows form (``/etc/passwd``, ``C:\\x``, ``\\\\host\\x``);
* :func:`resolve_inside`: the name on disk: the same check, then every symbolic link resolved
  (:meth:`pathlib.Path.resolve`) and the result required to lie inside the resolved folder.  A
  link that stays inside is fine; one that leads out, or a loop, is refused.  The caller gets
  the resolved path and reads that, never the name as given.

Both raise or return one line naming the file that gave the name and the entry (the caller's
``where``); :class:`OutsideFolder` is a ``ValueError``, so the command line prints it as
``envcap: error: ...`` with exit status 2.
"""

from __future__ import annotations

import os
from pathlib import Path, PurePosixPath, PureWindowsPath

__all__ = ["OutsideFolder", "name_problem", "resolve_inside"]


class OutsideFolder(ValueError):
    """A name from an untrusted file that does not stay inside its folder (one line)."""


def name_problem(name: object) -> str | None:
    """Why ``name`` is not a relative path inside a folder, judged on the name alone (a phrase
    such as ``"an absolute path, outside it"``), or ``None`` when it is one."""
    if not isinstance(name, str):
        return f"not a string but {type(name).__name__}"
    if not name:
        return "empty"
    if "\x00" in name:
        return "it holds a NUL character"
    if "\\" in name:
        return "it holds a backslash (names are '/'-separated), which may lead outside it"
    posix, win = PurePosixPath(name), PureWindowsPath(name)
    if posix.is_absolute() or win.is_absolute() or win.drive or win.root:
        return "an absolute path, outside it"
    if ".." in posix.parts:
        return "'..' leads outside it"
    if not posix.parts:
        return "it names the folder itself, not a file in it"
    return None


def resolve_inside(folder: str | os.PathLike[str], name: object, where: str, inside: str = "the probe set") -> Path:
    """``folder / name`` with every symbolic link resolved, checked to lie inside ``folder``
    (itself resolved); the file need not exist.  ``OutsideFolder`` (``"{where}: {name!r} is not a
    path inside {inside}: ..."``) for a name :func:`name_problem` refuses, a link that leads out
    of ``folder`` or a loop of links."""
    problem = name_problem(name)
    if problem is not None:
        raise OutsideFolder(f"{where}: {name!r} is not a path inside {inside}: {problem}")
    base = Path(folder).resolve()
    try:
        target = (base / str(name)).resolve()
    except (OSError, RuntimeError) as exc:   # a loop of links: RuntimeError up to Python 3.12, OSError after
        raise OutsideFolder(f"{where}: {name!r} cannot be resolved inside {inside} ({exc}); refused as outside it") from None
    if not target.is_relative_to(base):
        raise OutsideFolder(f"{where}: {name!r} is not a path inside {inside}: a symbolic link leads outside it, "
                            f"to {target}")
    return target
