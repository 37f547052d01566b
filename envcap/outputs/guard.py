"""Which paths envcap may write an output directory to: checked before any work is done.

The rules (``OutputRefused`` says which one a path breaks):

* the output is not a file, and the closest existing folder above it is a writable directory;
* the output is not reached through a symbolic link whose target does not exist (envcap never
  writes through a link it did not make: it would create whatever the link names);
* the output is never an input, an ancestor of an input, the working directory or an ancestor
  of it, whatever ``force`` says;
* the output is never the file system root, an existing top-level directory (``/etc``,
  ``/usr``, ``/home``, ...), a mount point, the home directory or a folder above it, whatever
  ``force`` says (:func:`check_protected`);
* an existing non-empty output directory is replaced only when envcap wrote it (it carries the
  marker of :mod:`envcap.outputs.marker`); with ``force`` one that envcap did not write is
  moved aside to ``NAME.envcap-replaced-YYYYmmdd-HHMMSS`` (:func:`envcap.outputs.swap.move_aside`),
  never deleted.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from envcap.outputs.marker import MARKER_NAME, PNG_MARK, is_replaceable, png_marked


class OutputRefused(ValueError):
    """envcap will not write an output there; the message says why and what to do instead."""


def dangling_link(path: str | os.PathLike[str]) -> Path | None:
    """The first symbolic link on the way to ``path`` (``path`` itself or a folder above it) whose
    target does not exist, else ``None``.  Writing there would create the link's target: a file or
    folder somewhere the link, not the user's command, names."""
    p = Path(os.path.abspath(os.fspath(path)))
    for step in [*reversed(p.parents), p]:
        if os.path.islink(step):
            try:
                os.stat(step)
            except FileNotFoundError:
                return step
            except OSError:     # a loop of links: resolve_output names it
                return None
        elif not os.path.lexists(step):
            return None     # nothing further down exists, links included
    return None


def check_no_dangling_link(path: str | os.PathLike[str]) -> None:
    """Refuse (:class:`OutputRefused`) an output ``path`` through a symbolic link whose target does
    not exist (:func:`dangling_link`): envcap never writes through a link it did not make."""
    link = dangling_link(path)
    if link is not None:
        named = "" if link == Path(os.path.abspath(os.fspath(path))) else f" (on the way to {path})"
        raise OutputRefused(f"output {link} is a symbolic link to {os.readlink(link)}, which does not exist"
                            f"{named}; envcap does not write through a link it did not make: remove the link, "
                            f"or choose another output")


def resolve_output(path: str | os.PathLike[str]) -> Path:
    """The absolute path, symbolic links resolved, that an output named ``path`` will have.
    Refused (:class:`OutputRefused`): a loop of links, a link whose target does not exist on the
    way (:func:`check_no_dangling_link`), the file system root."""
    check_no_dangling_link(path)
    try:
        final = Path(os.path.abspath(os.fspath(path))).resolve()
    except (RuntimeError, OSError) as exc:   # a loop of symbolic links (Python 3.11: RuntimeError)
        raise OutputRefused(f"output {path} cannot be resolved: a loop of symbolic links "
                            f"({' '.join(str(exc).split())})") from None
    if final.parent == final:
        raise OutputRefused(f"output directory {final} is the file system root")
    return final


def _contains(outer: Path, inner: Path) -> bool:
    return outer == inner or outer in inner.parents


def check_not_inputs(final: Path, inputs: Iterable[str | os.PathLike[str]]) -> None:
    """Refuse an output ``final`` that is one of ``inputs`` or contains one (``--force`` or not)."""
    for item in inputs:
        src = Path(os.path.abspath(os.fspath(item))).resolve()
        if _contains(final, src):
            what = "is the input" if final == src else "contains the input"
            raise OutputRefused(f"output directory {final} {what} {src}; choose another output directory "
                                f"(--force does not change this)")


def protected_reason(final: Path, *, root: Path | None = None, home: Path | None = None) -> str | None:
    """Why the absolute, resolved output path ``final`` may never be written, ``--force`` or not;
    ``None`` when it may.  ``root``: the file system root (default: ``final``'s anchor, ``/``);
    ``home``: the user's home directory (default: ``Path.home()`` resolved, when there is one).
    Tests pass temporary stand-ins for both."""
    root = Path(final.anchor) if root is None else root
    if final == root:
        return "is the file system root"
    if home is None:
        try:
            home = Path.home().resolve()
        except (RuntimeError, KeyError, OSError):
            home = None
    if home is not None and _contains(final, home):
        return "is the home directory" if final == home else f"contains the home directory {home}"
    if final.parent == root and final.exists():
        return "is a top-level system directory"
    if final.exists() and os.path.ismount(final):
        return "is a mount point"
    return None


def check_protected(final: Path, *, root: Path | None = None, home: Path | None = None) -> None:
    """Refuse (:class:`OutputRefused`) an output that :func:`protected_reason` names."""
    why = protected_reason(final, root=root, home=home)
    if why is not None:
        raise OutputRefused(f"output directory {final} {why}; choose another output directory "
                            f"(--force does not change this)")


def check_output_target(final: Path, inputs: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Check, before any work, that the output directory ``final`` (from :func:`resolve_output`)
    may be written: not protected (:func:`check_protected`), not a file, not an input or the
    working directory or above them, and the closest existing folder above it a writable
    directory.  Raises :class:`OutputRefused`."""
    check_protected(final)
    cwd = Path.cwd().resolve()
    if _contains(final, cwd):
        what = "is" if final == cwd else "contains"
        raise OutputRefused(f"output directory {final} {what} the working directory; choose another output "
                            f"directory (--force does not change this)")
    check_not_inputs(final, inputs)
    check_writable(final)


def creation_refused(folder: Path) -> str | None:
    """Why nothing can be created in the existing directory ``folder`` (the system's reason, in
    words), or ``None`` when a folder can be: tried for real (a folder ``.envcap-write-test-*``
    made and removed at once), since permissions do not tell (``root`` passes every permission
    check, yet ``/proc`` or a read-only mount takes no new entry)."""
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".envcap-write-test-", dir=folder))
    except OSError as exc:
        return (exc.strerror or str(exc)).lower()
    return None


def check_file_target(final: Path) -> None:
    """Refuse a single-file output ``final`` whose folder cannot be created or written: below a
    file, or a folder without write permission or that takes no new entry (:func:`creation_refused`)."""
    above = final.parent
    while not above.exists():
        above = above.parent
    if not above.is_dir():
        raise OutputRefused(f"cannot write output {final}: {above} is a file, not a folder")
    if not os.access(above, os.W_OK | os.X_OK):
        raise OutputRefused(f"cannot write output {final}: the folder {above} is not writable")
    why = creation_refused(above)
    if why is not None:
        raise OutputRefused(f"cannot write output {final}: nothing can be created in {above} ({why})")


def check_writable(folder: Path) -> None:
    """Refuse a ``folder`` that cannot be created or written: a file, or below a file or a
    folder without write permission, or one that takes no new entry (a read-only file system,
    ``/proc``: :func:`creation_refused`)."""
    if folder.exists() and not folder.is_dir():
        raise OutputRefused(f"output path {folder} exists and is not a directory")
    above = folder.parent
    while not above.exists():
        above = above.parent
    if not above.is_dir():
        raise OutputRefused(f"cannot create output directory {folder}: {above} is not a directory")
    if not os.access(above, os.W_OK | os.X_OK):
        raise OutputRefused(f"cannot create output directory {folder}: {above} is not writable")
    why = creation_refused(above)
    if why is not None:
        raise OutputRefused(f"cannot create output directory {folder}: nothing can be created in {above} ({why})")
    if folder.exists() and not os.access(folder, os.W_OK | os.X_OK):
        raise OutputRefused(f"cannot write output directory {folder}: it is not writable")


def check_replaceable(final: Path, force: bool) -> None:
    """Refuse to replace a non-empty directory that envcap did not write, unless ``force`` (which
    moves it aside when the new output is in place)."""
    if not force and not is_replaceable(final):
        raise OutputRefused(f"output directory {final} is not empty and was not written by envcap "
                            f"(it has no {MARKER_NAME} file); choose another output directory, "
                            f"or use --force to move it aside (it is renamed, never deleted)")


def check_file_replaceable(path: Path, force: bool) -> None:
    """Refuse to overwrite an existing file that envcap did not write (a PNG without
    :data:`~envcap.outputs.marker.PNG_MARK`), unless ``force``."""
    if not force and path.exists() and not png_marked(path):
        raise OutputRefused(f"{path} exists and was not written by envcap (no '{PNG_MARK[0]}: {PNG_MARK[1]}' "
                            f"PNG text); choose another folder, or use --force to move it aside")
