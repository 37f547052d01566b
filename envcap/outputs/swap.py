"""Put a complete new output directory in place of the old one, so that the output path always
names a complete output: the old one until the new one is in place, then the new one.

Names beside an output ``NAME`` (all in its folder, all envcap's own):

* ``.NAME.tmp-XXXXXXXX/`` (8 hex digits): a new output being written (:func:`make_temp_dir`);
* ``.NAME.tmp-XXXXXXXX.EXT``: a new single file (``NAME.EXT``) being written
  (:func:`make_temp_file`; earlier versions' names had 8 of ``[a-z0-9_]``, ``tempfile``'s);
* ``.NAME.old/``: the old output set aside during a two-step swap;
* ``.NAME.swap``: the journal of a two-step swap, present from before the first rename until
  after the second;
* ``NAME.envcap-replaced-YYYYmmdd-HHMMSS[-K]``: an output that envcap did NOT write, replaced
  with ``--force``: moved aside (never deleted), visible, for the user to keep or remove
  (:func:`move_aside`).

On Linux the swap is one ``renameat2(RENAME_EXCHANGE)`` system call: the output path names the
old directory, then the new one, never nothing; the old one then lies under the temporary name
and is removed.  Where that call is missing (other systems, some file systems) the swap takes
two renames (old aside, new in) inside the journal.  Both run with SIGINT/SIGTERM held back;
a SIGKILL between the two renames leaves the journal, the old output set aside and no output,
and :func:`recover` (run by the next writer of that output, under its lock) puts the old output
back.  :func:`recover` also removes every leftover temporary directory, :func:`recover_file` the
leftover temporary files of a single-file output (under that output's lock, so never a live one).
"""

from __future__ import annotations

import ctypes
import errno
import os
import re
import secrets
import shutil
import sys
import time
from pathlib import Path

from envcap.outputs.deferred_signals import deferred_signals

_AT_FDCWD = -100
_RENAME_NOREPLACE = 1
_RENAME_EXCHANGE = 2
_UNSUPPORTED = {errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP}


def _load_renameat2():  # -> the libc function, or None where there is none
    if not sys.platform.startswith("linux"):
        return None
    fn = getattr(ctypes.CDLL(None, use_errno=True), "renameat2", None)
    if fn is not None:
        fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
        fn.restype = ctypes.c_int
    return fn


_RENAMEAT2 = _load_renameat2()
HAS_EXCHANGE = _RENAMEAT2 is not None  # this system has renameat2 (a file system may still refuse it)


def temp_name_pattern(final: Path) -> re.Pattern[str]:
    """Names of the temporary directories of output ``final`` (see the module docstring)."""
    return re.compile(rf"\.{re.escape(final.name)}\.tmp-[0-9a-f]{{8}}")


def temp_file_pattern(final: Path) -> re.Pattern[str]:
    """Names of the temporary files of the single-file output ``final`` (module docstring)."""
    return re.compile(rf"\.{re.escape(final.name)}\.tmp-[a-z0-9_]{{8}}{re.escape(final.suffix)}")


def make_temp_file(final: Path) -> Path:
    """Create an empty owner-only temporary file ``.NAME.tmp-XXXXXXXX.EXT`` beside ``final``."""
    while True:
        tmp = final.with_name(f".{final.name}.tmp-{secrets.token_hex(4)}{final.suffix}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o600))
            return tmp
        except FileExistsError:
            continue


def recover_file(final: Path) -> list[Path]:
    """Remove the temporary files a killed writer of the single-file output ``final`` left (only
    envcap's names, :func:`temp_file_pattern`; regular files only).  Call with the output's lock
    held.  Returns the paths removed."""
    pattern, removed = temp_file_pattern(final), []
    with deferred_signals():
        for entry in sorted(final.parent.iterdir()):
            if pattern.fullmatch(entry.name) and entry.is_file() and not entry.is_symlink():
                entry.unlink(missing_ok=True)
                removed.append(entry)
    return removed


def aside_path(final: Path) -> Path:
    return final.with_name(f".{final.name}.old")


def journal_path(final: Path) -> Path:
    return final.with_name(f".{final.name}.swap")


def make_temp_dir(final: Path) -> Path:
    """Create an empty owner-only temporary directory ``.NAME.tmp-XXXXXXXX`` beside ``final``."""
    while True:
        tmp = final.with_name(f".{final.name}.tmp-{secrets.token_hex(4)}")
        try:
            tmp.mkdir(mode=0o700)
            return tmp
        except FileExistsError:
            continue


def replaced_name(path: Path, when: float | None = None, k: int = 1) -> Path:
    """The name a foreign output ``path`` is moved to when ``--force`` replaces it:
    ``NAME.envcap-replaced-YYYYmmdd-HHMMSS`` beside it (local time ``when``, default now; a
    file keeps its extension last: ``walker.envcap-replaced-...glb``), ``-K`` added for ``k > 1``."""
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(when))
    tag = f".envcap-replaced-{stamp}" + (f"-{k}" if k > 1 else "")
    if path.is_dir() or not path.suffix:
        return path.with_name(path.name + tag)
    return path.with_name(path.stem + tag + path.suffix)


def _rename_noreplace(src: Path, dst: Path) -> None:
    """Rename ``src`` to ``dst``; ``FileExistsError`` if ``dst`` exists (``renameat2`` with
    ``RENAME_NOREPLACE`` where the system has it, else a check just before the rename)."""
    if _RENAMEAT2 is not None:
        if _RENAMEAT2(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), _RENAME_NOREPLACE) == 0:
            return
        err = ctypes.get_errno()
        if err not in _UNSUPPORTED:
            raise OSError(err, os.strerror(err), str(src), None, str(dst))
    if os.path.lexists(dst):
        raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
    os.rename(src, dst)


def move_aside(path: Path) -> Path:
    """Move the file or directory ``path`` (one envcap did not write) to :func:`replaced_name`
    beside it, never over an existing name; return where it went.  Nothing is copied or
    deleted: one rename in the same folder."""
    now = time.time()
    for k in range(1, 1000):
        target = replaced_name(path, now, k)
        try:
            _rename_noreplace(path, target)
            return target
        except FileExistsError:
            continue
    raise OSError(f"cannot move {path} aside: 999 names {replaced_name(path, now)}-K are taken")


def exchange(a: Path, b: Path) -> bool:
    """Swap the names ``a`` and ``b`` in one system call; False where the system or the file
    system cannot (nothing is changed then)."""
    if _RENAMEAT2 is None:
        return False
    if _RENAMEAT2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in _UNSUPPORTED:
        return False
    raise OSError(err, os.strerror(err), str(a), None, str(b))


def remove_path(path: Path) -> None:
    """Remove a file or a whole directory tree (not following a symbolic link); no error if gone."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def install(tmp: Path, final: Path, *, use_exchange: bool = True, keep_old: bool = False) -> Path | None:
    """Make the complete directory ``tmp`` the output ``final`` and remove the old output, or,
    with ``keep_old`` (an old output envcap did not write), move the old one aside
    (:func:`move_aside`) and return where it went (``None`` otherwise).

    The caller holds the output's lock.  ``use_exchange=False`` takes the two-step path even
    where the one-call exchange exists.  A kill between the two renames of ``keep_old`` leaves
    the old output under its new name and no output: nothing is lost.
    """
    with deferred_signals():
        if not final.exists():
            os.rename(tmp, final)
            return None
        if keep_old:
            aside = move_aside(final)
            try:
                os.rename(tmp, final)
            except BaseException:
                os.rename(aside, final)
                raise
            return aside
        if use_exchange and exchange(tmp, final):
            remove_path(tmp)  # now the old output
            return None
        journal, aside = journal_path(final), aside_path(final)
        remove_path(aside)
        journal.touch()
        os.rename(final, aside)
        try:
            os.rename(tmp, final)
        except BaseException:
            os.rename(aside, final)
            journal.unlink()
            raise
        journal.unlink()
        remove_path(aside)
    return None


def recover(final: Path) -> list[Path]:
    """Finish what an interrupted writer of ``final`` left: put back an old output set aside by a
    half-done two-step swap, then remove every temporary directory and the set-aside copy.

    Call with the output's lock held.  Returns the leftover paths that were removed.
    """
    removed: list[Path] = []
    journal, aside = journal_path(final), aside_path(final)
    pattern = temp_name_pattern(final)
    with deferred_signals():
        if journal.exists():
            if not final.exists() and aside.is_dir():
                os.rename(aside, final)
            journal.unlink()
        if aside.exists() or aside.is_symlink():
            remove_path(aside)
            removed.append(aside)
        for entry in sorted(final.parent.iterdir()):
            if pattern.fullmatch(entry.name):
                remove_path(entry)
                removed.append(entry)
    return removed
