"""Write outputs so that a failed run leaves nothing half-written behind.

Everything is written under a temporary sibling name and renamed into place at the end.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def _publish_mode(path: Path, is_dir: bool) -> None:
    """Give a temporary file or directory (created owner-only by tempfile) the usual mode."""
    os.chmod(path, (0o777 if is_dir else 0o666) & ~_umask())


@contextlib.contextmanager
def atomic_output_dir(path: str | os.PathLike[str], overwrite: bool = True) -> Iterator[Path]:
    """Yield a temporary directory that becomes ``path`` when the block ends without error.

    On error the temporary directory is removed and ``path`` is left as it was.  With
    ``overwrite`` an existing ``path`` is replaced (only after the new content is complete);
    without it an existing non-empty ``path`` is an error.
    """
    final = Path(path).resolve()
    if final.exists() and not final.is_dir():
        raise FileExistsError(f"output path {final} exists and is not a directory")
    if final.exists() and any(final.iterdir()) and not overwrite:
        raise FileExistsError(f"output directory {final} is not empty")
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.tmp-", dir=final.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _publish_mode(tmp, True)
    old = None
    if final.exists():
        old = final.with_name(f".{final.name}.old-{os.getpid()}")
        os.replace(final, old)
    os.replace(tmp, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


@contextlib.contextmanager
def atomic_output_file(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary file path in the same directory that becomes ``path`` on success."""
    final = Path(path).resolve()
    final.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{final.name}.tmp-", dir=final.parent, suffix=final.suffix)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _publish_mode(tmp, False)
    os.replace(tmp, final)
