"""Input paths: say what a path that should name a file (or a folder) is instead, before opening it.

``Path.is_file()`` is False for a missing file, a folder, a FIFO, a device, a socket and a broken
symbolic link alike; an error that said "not found" for each of them sent users looking for a file
that is there.  :func:`require_file` and :func:`require_dir` tell them apart with one ``stat`` (a
FIFO is never opened, so a reader never blocks on it) and raise one line naming the path and
what it is:

* missing: ``FileNotFoundError`` with the caller's "not found" text;
* a broken symbolic link: ``FileNotFoundError`` (``... is a symbolic link to PATH, which does not exist``);
* a folder where a file is needed, a file where a folder is needed, a FIFO, a character or block
  device (``/dev/zero``), a socket: ``ValueError`` (``... is a FIFO (named pipe), not a regular file``).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISREG, "a regular file"))


def path_kind(path: str | os.PathLike[str]) -> str | None:
    """What ``path`` names, symbolic links followed: ``"a regular file"``, ``"a directory"``,
    ``"a FIFO (named pipe)"``, ``"a character device"``, ...; ``None`` when nothing is there."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:   # a loop of links, a name too long, no permission on a folder above
        return f"unreadable ({exc.strerror.lower() if exc.strerror else exc})"
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def _missing(p: Path, not_found: str) -> FileNotFoundError:
    if os.path.islink(p):
        return FileNotFoundError(f"{not_found} ({p} is a symbolic link to {os.readlink(p)}, which does not exist)")
    return FileNotFoundError(not_found)


def require_file(path: str | os.PathLike[str], what: str, not_found: str | None = None) -> Path:
    """``path`` as a ``Path`` when it names a regular file (links followed); else one line:
    ``FileNotFoundError`` (``not_found``, default ``"{what} not found: {path}"``) or ``ValueError``
    (``"{what} {path} is a directory, not a regular file"``, a FIFO, a device, ...)."""
    p = Path(path)
    kind = path_kind(p)
    if kind == "a regular file":
        return p
    if kind is None:
        raise _missing(p, not_found or f"{what} not found: {p}")
    raise ValueError(f"{what} {p} is {kind}, not a regular file")


def require_dir(path: str | os.PathLike[str], what: str, not_found: str | None = None) -> Path:
    """``path`` as a ``Path`` when it names a directory; else ``FileNotFoundError`` (``not_found``,
    default ``"{what} not found: {path}"``) or ``ValueError`` (``"{what} {path} is a regular file,
    not a directory"``)."""
    p = Path(path)
    kind = path_kind(p)
    if kind == "a directory":
        return p
    if kind is None:
        raise _missing(p, not_found or f"{what} not found: {p}")
    raise ValueError(f"{what} {p} is {kind}, not a directory")
