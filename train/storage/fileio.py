"""Every file ecorl writes goes through here: atomic replacement and advisory locks.

* `atomic_file` / `atomic_path`: write under a unique temporary name in the target's directory, fsync, then
  ``os.replace`` onto the target. A crash or SIGKILL at any point leaves the old file or the new one, never a
  mix; the temporary is removed when the block raises. Temporary names (`is_temporary`) carry the writer's
  pid and a random token after ``.ecorl-tmp-``, so two writers never share one and no user file matches.
  The target's directory must be a real directory (`train.storage.safeio.real_dir`), not a link.
* `FileLock`: an exclusive ``fcntl.flock`` on a lock file (opened with ``O_NOFOLLOW``, never truncated),
  taken without waiting; a second holder is refused with the first one's pid. The kernel releases it
  when the process dies, however it dies.
"""

from __future__ import annotations

import errno
import fcntl
import os
import re
import secrets
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

from train.storage.safeio import UnsafeFileError, real_dir

TEMP_MARK = ".ecorl-tmp-"
"""Part of every temporary file name (see `temporary_name`)."""
_TEMPORARY = re.compile(r"\.[^/]*\.ecorl-tmp-[0-9]+-[0-9a-f]{8}(\.[^./]+)?")
"""What `temporary_name` makes, and nothing a user would name a file."""
LOCK_BYTES = 24
"""Size of what a lock file holds (its holder's pid, padded); a larger file is not a lock of ecorl's."""

_replace = os.replace
"""The final rename (a module attribute so that kill tests can interrupt a write right before it)."""


def temporary_name(path: Path) -> Path:
    """A fresh hidden name beside ``path`` that keeps its suffix: ``.STEM.ecorl-tmp-PID-RANDOM.SUFFIX``."""
    return path.with_name(f".{path.stem}{TEMP_MARK}{os.getpid()}-{secrets.token_hex(4)}{path.suffix}")


def is_temporary(name: str) -> bool:
    """True for a name made by `temporary_name` (what an interrupted write may leave behind), and for no
    name a user would choose (``.notes.tmp.txt`` is not one).
    """
    return _TEMPORARY.fullmatch(name) is not None


def fsync_path(path: Path) -> None:
    """Flush ``path`` to disk: a file written by name (by a library), or a directory, to make a rename
    inside it durable.
    """
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path for a library that writes files by name; on success it replaces ``path``.

    The parent directory is created. If the block raises, the temporary is removed and ``path`` is untouched.
    """
    path = Path(path)
    real_dir(path.parent)
    tmp = temporary_name(path)
    try:
        open(tmp, "xb").close()  # an unwritable place fails here, by name, not deep inside a library
    except OSError as err:
        raise OSError(f"cannot write {path}: {err.strerror or err}; choose a writable location") from None
    try:
        yield tmp
        fsync_path(tmp)
        _replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    fsync_path(path.parent)


@contextmanager
def atomic_dir(path: str | Path, doing: str) -> Iterator[Path]:
    """Yield a hidden folder beside ``path`` (``.NAME.DOING-PID``, not yet created) to build a directory in; when
    the block completes it replaces ``path``, which must be absent or empty. The folder never outlives the block:
    an interrupted or failed build leaves ``path`` as it was.
    """
    import shutil

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    building = path.parent / f".{path.name}.{doing}-{os.getpid()}"
    shutil.rmtree(building, ignore_errors=True)
    try:
        yield building
        if path.exists():
            path.rmdir()  # empty: a directory with anything in it is refused here, not overwritten
        os.rename(building, path)
    finally:
        shutil.rmtree(building, ignore_errors=True)


@contextmanager
def atomic_file(path: str | Path) -> Iterator[BinaryIO]:
    """Open a binary temporary file that replaces ``path`` (after fsync) only if the block completes."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        yield f
        f.flush()
        os.fsync(f.fileno())


def atomic_write(path: str | Path, *chunks: bytes | memoryview) -> Path:
    """Write ``chunks`` to ``path`` atomically (see `atomic_file`); return the path."""
    with atomic_file(path) as f:
        for chunk in chunks:
            f.write(chunk)
    return Path(path)


def atomic_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; return the path."""
    return atomic_write(path, text.encode())


class LockedError(RuntimeError):
    """Another process holds the lock (the message names its pid and what to do)."""


def open_lock_file(path: Path) -> int:
    """A descriptor of the lock file ``path``, created if missing; never a link, never someone else's file.

    Opened with ``O_NOFOLLOW | O_CREAT`` and no truncation: a symbolic link, a FIFO, a file with other
    hard links or one larger than `LOCK_BYTES` is refused (it cannot be a lock ecorl made) and left as it is.
    """
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o644)
    except OSError as err:
        if err.errno != errno.ELOOP:
            raise
        raise UnsafeFileError(f"{path} is a symbolic link, not a lock file of ecorl; remove the link") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1 or info.st_size > LOCK_BYTES:
        os.close(fd)
        raise UnsafeFileError(f"{path} is not a lock file of ecorl (not a small regular file with one link); "
                              f"move it away")
    return fd


class FileLock:
    """An exclusive, non-blocking advisory lock on ``path`` (created if needed), held until `release`.

    ``what`` names the locked thing in the refusal message, e.g. "run directory runs/x".
    """

    def __init__(self, path: str | Path, what: str, advice: str) -> None:
        self.path, self.what, self.advice = Path(path), what, advice
        self._fd: int | None = None

    def acquire(self) -> FileLock:
        """Take the lock or raise `LockedError` naming the holder's pid."""
        fd = open_lock_file(self.path)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            if err.errno in (errno.EAGAIN, errno.EACCES):
                raise LockedError(f"{self.what} is in use by another ecorl process (pid {holder}); "
                                  f"{self.advice}") from None
            raise
        os.pwrite(fd, f"{os.getpid()}\n".ljust(LOCK_BYTES).encode(), 0)
        self._fd = fd
        return self

    def release(self) -> None:
        """Give the lock up (idempotent); the lock file stays, blank."""
        if self._fd is not None:
            os.pwrite(self._fd, b" " * LOCK_BYTES, 0)
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __del__(self) -> None:  # an abandoned holder (e.g. a trainer never closed) frees the lock
        try:
            self.release()
        except Exception:  # at interpreter exit the kernel frees the lock anyway
            pass

    @property
    def held(self) -> bool:
        """True while this object holds the lock."""
        return self._fd is not None

    def __enter__(self) -> FileLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
