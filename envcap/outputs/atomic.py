"""Write outputs so that a failed or interrupted run leaves nothing half-written behind.

An output directory is written under a temporary sibling name, marked as envcap's
(:mod:`envcap.outputs.marker`) and put in place of the old one at the end
(:mod:`envcap.outputs.swap`), under the output's lock (:mod:`envcap.outputs.claim`).  A single
file is written under a temporary sibling name and renamed into place.
"""

from __future__ import annotations

import contextlib
import errno
import os
import sys
from collections.abc import Iterator
from pathlib import Path

from envcap.outputs.claim import OutputClaim, claim_output_dir, make_parents, remove_if_empty
from envcap.outputs.deferred_signals import deferred_signals
from envcap.outputs.guard import check_replaceable, resolve_output
from envcap.outputs.lock import OutputLock
from envcap.outputs.marker import is_replaceable, read_marker, write_marker
from envcap.outputs.swap import install, make_temp_dir, make_temp_file, move_aside, recover, recover_file, remove_path


class DiskFull(OSError):
    """A write failed for want of space (``ENOSPC``) or quota (``EDQUOT``); the message is one line
    naming the output and saying the disk is full.  What was written is removed."""

    def __str__(self) -> str:
        return str(self.args[0])


def disk_full(exc: BaseException, output: Path, staging: Path | None = None) -> DiskFull | None:
    """The :class:`DiskFull` error for ``exc`` raised while writing ``output``, or ``None`` when
    ``exc`` is not a full disk (an ``OSError`` with ``ENOSPC`` / ``EDQUOT``, or a library error
    whose text says "No space left on device").  ``staging``: the temporary directory being
    filled; a file in it that failed is named relative to the output (``out (exr/probe_011.exr)``)."""
    code = getattr(exc, "errno", None)
    if code not in (errno.ENOSPC, errno.EDQUOT) and "no space left on device" not in str(exc).lower():
        return None
    where = str(output)
    inner = getattr(exc, "filename", None)
    if staging is not None and inner:
        try:
            where += f" ({Path(inner).relative_to(staging).as_posix()})"
        except ValueError:
            pass
    what = "the disk quota is used up" if code == errno.EDQUOT else "no space left on the device: the disk is full"
    err = DiskFull(f"cannot write {where}: {what}; nothing half-written was left (free some space, or choose an output "
                   f"on another disk)")
    err.errno = errno.EDQUOT if code == errno.EDQUOT else errno.ENOSPC
    err.filename = str(output)
    return err


def report_moved_aside(what: Path, aside: Path) -> None:
    """The one line that says where ``--force`` put an output envcap did not write."""
    print(f"envcap: note: {what} was not written by envcap: moved it to {aside} (nothing was deleted)",
          file=sys.stderr, flush=True)


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def _publish_mode(path: Path, is_dir: bool) -> None:
    """Give a temporary file or directory (created owner-only) the usual mode."""
    os.chmod(path, (0o777 if is_dir else 0o666) & ~_umask())


@contextlib.contextmanager
def _staged(claim: OutputClaim) -> Iterator[Path]:
    if not claim.held:
        raise RuntimeError(f"the claim on {claim.path} has been released; claim the output again")
    tmp = make_temp_dir(claim.path)
    try:
        yield tmp
        write_marker(tmp, claim.kind)
        _publish_mode(tmp, True)
        check_replaceable(claim.path, claim.force)  # nothing foreign appeared while we worked
        foreign = not is_replaceable(claim.path)     # only with force: moved aside, never removed
        aside = install(tmp, claim.path, keep_old=foreign)
        if aside is not None:
            claim.moved_aside = aside
            report_moved_aside(claim.path, aside)
    except BaseException as exc:
        with deferred_signals():
            remove_path(tmp)
        full = disk_full(exc, claim.path, tmp)
        if full is not None:
            raise full from None
        raise


@contextlib.contextmanager
def atomic_output_dir(target: str | os.PathLike[str], *, kind: str = "output", force: bool = False) -> Iterator[Path]:
    """Yield an empty temporary directory that becomes the output ``target`` when the block ends
    without error.

    ``target`` is an :class:`~envcap.outputs.claim.OutputClaim` (claimed before the work began;
    its kind and force apply) or a path, which is claimed here (``kind``, ``force``: see
    :func:`~envcap.outputs.claim.claim_output_dir`): refused when it is a file, the working
    directory or a non-empty directory without envcap's marker (unless ``force``), or when
    another process is writing it.  On error or interrupt the temporary directory is removed and
    the output is left as it was; on success the output carries the marker, and the old output
    is replaced only once the new one is complete.
    """
    if isinstance(target, OutputClaim):
        with _staged(target) as tmp:
            yield tmp
        return
    with claim_output_dir(target, kind=kind, force=force) as claim, _staged(claim) as tmp:
        yield tmp


@contextlib.contextmanager
def atomic_output_file(path: str | os.PathLike[str], *, keep_existing: bool = False, lock: bool = False) -> Iterator[Path]:
    """Yield a temporary file path ``.NAME.tmp-XXXXXXXX.EXT`` in the same directory that becomes
    ``path`` on success; on error it is removed.

    ``keep_existing``: an existing ``path`` (a file envcap did not write, replaced with
    ``--force``) is moved aside (:func:`~envcap.outputs.swap.move_aside`, reported on stderr)
    instead of overwritten.  ``lock``: a file that is a command's whole output (``avatar --out``,
    ``scenes --preview``): take its lock first (:mod:`envcap.outputs.lock`: a second run fails at
    once) and remove what killed runs left (:func:`~envcap.outputs.swap.recover_file`).  Files
    written inside an output directory need neither (the directory's claim covers them).
    Missing folders above ``path`` are created, and removed again if the write fails.  A path
    through a symbolic link whose target does not exist is refused
    (:func:`~envcap.outputs.guard.resolve_output`)."""
    final = resolve_output(path)
    created = make_parents(final.parent)
    try:
        with contextlib.ExitStack() as stack:
            if lock:
                held = OutputLock(final)
                stack.callback(held.release)
                recover_file(final)
            tmp = make_temp_file(final)
            try:
                yield tmp
            except BaseException:
                with deferred_signals():
                    tmp.unlink(missing_ok=True)
                raise
            try:
                _publish_mode(tmp, False)
                with deferred_signals():
                    aside = move_aside(final) if keep_existing and os.path.lexists(final) else None
                    os.replace(tmp, final)
            except BaseException:
                with deferred_signals():
                    tmp.unlink(missing_ok=True)
                raise
    except BaseException as exc:
        remove_if_empty(created)
        full = disk_full(exc, final)
        if full is not None:
            raise full from None
        raise
    if aside is not None:
        report_moved_aside(final, aside)


def retire_output_dir(path: str | os.PathLike[str]) -> bool:
    """Remove the output directory ``path`` when envcap wrote it (it carries the marker of
    :mod:`envcap.outputs.marker`) and a run has made it stale (``envcap demo --no-eval``: an
    evaluation of earlier probes).  Under the output's lock: renamed to a temporary name first
    (a kill leaves only that, which the next run on the output removes), then removed.  Returns
    False, touching nothing, when there is no such directory or envcap did not write it."""
    if Path(path).is_symlink():      # a link the user made: neither it nor where it leads is removed
        return False
    final = resolve_output(path)
    if not final.is_dir() or read_marker(final) is None:
        return False
    lock = OutputLock(final)
    try:
        recover(final)
        if read_marker(final) is None:
            return False
        with deferred_signals():
            tmp = make_temp_dir(final)
            os.rmdir(tmp)
            os.rename(final, tmp)
        remove_path(tmp)
        return True
    finally:
        lock.release()
