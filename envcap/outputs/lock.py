"""One writer per output: an exclusive ``fcntl.flock`` on ``.NAME.lock`` beside the output ``NAME``.

The lock file holds the writer's process id (for the error message).  It is removed when the
lock is released; a writer killed with SIGKILL leaves the file but not the lock (the kernel
drops a dead process's locks), so the next writer takes it over and removes it in turn.  After
taking the lock, a writer checks that the file it locked is still the one on disk (another
writer may have removed it in between), and starts over when it is not.
"""

from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path

from envcap.outputs.guard import OutputRefused


class OutputBusy(RuntimeError):
    """Another process is writing the same output."""


def lock_path(final: Path) -> Path:
    """The lock file of output ``final``: ``.NAME.lock`` in the same folder."""
    return final.with_name(f".{final.name}.lock")


class OutputLock:
    """An exclusive, non-blocking lock on output ``final``; ``release()`` removes the lock file."""

    def __init__(self, final: Path) -> None:
        self.final = final
        self.path = lock_path(final)
        self._fd: int | None = None
        for _ in range(100):
            fd = self._open()
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
                os.close(fd)
                raise OutputBusy(f"another envcap run (process {holder}) is writing {final}; "
                                 f"wait for it to finish or choose another output") from None
            except BaseException:
                os.close(fd)
                raise
            if self._is_on_disk(fd):
                self._fd = fd
                try:   # the holder's pid is only for the message above: a full disk does not stop the run here
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                except OSError as exc:
                    if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
                        self.release()
                        raise
                return
            os.close(fd)  # removed by its previous holder after we opened it: start over
        raise OutputBusy(f"could not lock {final}: its lock file {self.path} keeps being replaced")

    def _open(self) -> int:
        """Open (create) the lock file; an ``OSError`` becomes one line naming it and the reason."""
        try:
            return os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except PermissionError:
            raise   # the caller says which folder is not writable
        except OSError as exc:
            why = (exc.strerror or str(exc)).lower()
            if exc.errno == errno.EISDIR:
                why = "a directory of that name is in the way (not envcap's; move it)"
            elif exc.errno == errno.ENOENT and self.path.parent.is_dir():
                why = f"the file system of {self.path.parent} does not allow new files there"
            elif exc.errno in (errno.ENOSPC, errno.EDQUOT):
                why = "no space left on the device (the disk is full)"
            raise OutputRefused(f"cannot write output {self.final}: cannot create its lock file {self.path}: {why}") from None

    def _is_on_disk(self, fd: int) -> bool:
        try:
            on_disk = os.stat(self.path)
        except FileNotFoundError:
            return False
        held = os.fstat(fd)
        return (on_disk.st_dev, on_disk.st_ino) == (held.st_dev, held.st_ino)

    @property
    def held(self) -> bool:
        return self._fd is not None

    def release(self) -> None:
        """Remove the lock file and drop the lock (in that order, so no one locks a removed file
        and believes it holds the lock)."""
        if self._fd is None:
            return
        try:
            self.path.unlink(missing_ok=True)
        finally:
            os.close(self._fd)
            self._fd = None
