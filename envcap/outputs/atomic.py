"""Write outputs so that a failed or interrupted run leaves nothing half-written behind.

An output directory is written under a temporary sibling name, marked as envcap's
(:mod:`envcap.outputs.marker`) and put in place of the old one at the end
(:mod:`envcap.outputs.swap`), under the output's lock (:mod:`envcap.outputs.claim`).  A single
file is written under a temporary sibling name and renamed into place.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

from envcap.outputs.claim import OutputClaim, claim_output_dir
from envcap.outputs.deferred_signals import deferred_signals
from envcap.outputs.guard import check_replaceable
from envcap.outputs.marker import is_replaceable, write_marker
from envcap.outputs.swap import install, make_temp_dir, move_aside, remove_path


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
    except BaseException:
        with deferred_signals():
            remove_path(tmp)
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
def atomic_output_file(path: str | os.PathLike[str], *, keep_existing: bool = False) -> Iterator[Path]:
    """Yield a temporary file path in the same directory that becomes ``path`` on success.

    ``keep_existing``: an existing ``path`` (a file envcap did not write, replaced with
    ``--force``) is moved aside (:func:`~envcap.outputs.swap.move_aside`, reported on stderr)
    instead of overwritten."""
    final = Path(path).resolve()
    final.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{final.name}.tmp-", dir=final.parent, suffix=final.suffix)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
    except BaseException:
        with deferred_signals():
            tmp.unlink(missing_ok=True)
        raise
    _publish_mode(tmp, False)
    with deferred_signals():
        aside = move_aside(final) if keep_existing and os.path.lexists(final) else None
        os.replace(tmp, final)
    if aside is not None:
        report_moved_aside(final, aside)
