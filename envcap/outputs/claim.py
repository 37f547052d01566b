"""Claim an output directory before the work that fills it: check it, lock it, clean up after
killed runs.

``claim_output_dir(path, kind=..., inputs=..., force=...)`` does, in this order, before the
caller starts its (long) work:

1. the checks of :mod:`envcap.outputs.guard` (not a file, not an input, not the working
   directory, a writable folder above it);
2. creates the missing folders above the output (removed again if the claim fails);
3. takes the output's lock (:mod:`envcap.outputs.lock`): a second run on the same output fails
   here, before doing any work, and leaves nothing;
4. recovers what a killed run left (:func:`envcap.outputs.swap.recover`);
5. refuses a non-empty directory that envcap did not write, unless ``force``.

The :class:`OutputClaim` it yields is an ``os.PathLike`` naming the output; pass it where a
writer takes an output path (``atomic_output_dir`` and the writers built on it, e.g.
``write_probe_set``), and the writer uses the claim (its lock, kind and ``force``) instead of
claiming the path again.  The lock is released when the block ends.
"""

from __future__ import annotations

import contextlib
import errno
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from envcap.outputs.deferred_signals import deferred_signals
from envcap.outputs.guard import OutputRefused, check_not_inputs, check_output_target, check_replaceable, resolve_output
from envcap.outputs.lock import OutputLock
from envcap.outputs.swap import recover


@dataclass
class OutputClaim(os.PathLike):
    """A locked output directory that the current process may replace.

    ``path`` is the absolute output path; ``kind`` goes into its marker; ``force`` allows
    replacing a non-empty directory that envcap did not write.
    """

    path: Path
    kind: str
    force: bool
    lock: OutputLock = field(repr=False)
    moved_aside: Path | None = None
    """Where ``--force`` moved an output envcap did not write (set when the new one is in place)."""

    def __fspath__(self) -> str:
        return str(self.path)

    @property
    def held(self) -> bool:
        """True until the ``claim_output_dir`` block that made this claim ends."""
        return self.lock.held

    def check_not_inputs(self, inputs: Iterable[str | os.PathLike[str]]) -> None:
        """Refuse inputs found after claiming (e.g. files a scene refers to) that lie in the output."""
        check_not_inputs(self.path, inputs)


def make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and the missing folders above it; return those created, deepest first.
    A folder that cannot be created is :class:`~envcap.outputs.guard.OutputRefused` naming it and
    why (a file in the way, no space, ...), the folders made so far removed again."""
    missing = []
    while not folder.exists():
        missing.append(folder)
        folder = folder.parent
    created: list[Path] = []
    for d in reversed(missing):
        try:
            d.mkdir()
        except FileExistsError:
            if d.is_dir():
                continue
            remove_if_empty(created[::-1])
            raise OutputRefused(f"cannot create folder {d}: a file of that name is in the way") from None
        except OSError as exc:
            remove_if_empty(created[::-1])
            why = (exc.strerror or str(exc)).lower()
            if exc.errno in (errno.ENOSPC, errno.EDQUOT):
                why = "no space left on the device (the disk is full)"
            raise OutputRefused(f"cannot create folder {d}: {why}") from None
        created.append(d)
    return created[::-1]


def remove_if_empty(folders: list[Path]) -> None:
    """Remove the folders :func:`make_parents` created (deepest first) while they are empty."""
    for d in folders:
        try:
            d.rmdir()
        except OSError:
            return


@contextlib.contextmanager
def claim_output_dir(path: str | os.PathLike[str], *, kind: str = "output",
                     inputs: Iterable[str | os.PathLike[str]] = (), force: bool = False) -> Iterator[OutputClaim]:
    """Check and lock the output directory ``path`` for the duration of the block (see the
    module docstring).  Raises :class:`~envcap.outputs.guard.OutputRefused` (a ``ValueError``)
    for a path envcap will not write to and :class:`~envcap.outputs.lock.OutputBusy` when
    another run holds the output."""
    final = resolve_output(path)
    check_output_target(final, inputs)
    created = make_parents(final.parent)
    try:
        lock = OutputLock(final)
    except PermissionError as exc:
        remove_if_empty(created)
        raise OutputRefused(f"cannot write output directory {final}: {exc.strerror} in {final.parent}") from None
    except BaseException:
        remove_if_empty(created)
        raise
    try:
        recover(final)
        check_replaceable(final, force)
        yield OutputClaim(final, kind, force, lock)
    except BaseException:
        with deferred_signals():
            lock.release()
            remove_if_empty(created)
        raise
    lock.release()
