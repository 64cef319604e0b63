"""Reading files that anyone may have crafted, and writing only where ecorl means to.

* `open_regular`: opens a file without following a final symbolic link and without blocking (a FIFO or a
  device is seen by ``fstat`` and refused, never read), so a planted ``metrics.csv -> /dev/zero`` or a FIFO
  named ``checkpoint.npz`` is a one-line error, not a read that never ends.
* `read_text` / `load_json`: bounded reads; JSON nested at most `MAX_JSON_DEPTH` deep, its numbers finite.
* `read_npy`: an ``.npy`` array whose header is checked (shape, dtype, size against a limit) before any
  memory is allocated for it.
* `real_dir`: a directory ecorl writes into must be a directory, not a symbolic link to one elsewhere.
* `regular_file` and `no_link_below`: a file handed to a library that opens it by name must be a regular file
  (not a FIFO, which would block it), reached through no link inside the tree ecorl was given.

Every refusal is an `UnsafeFileError` (a ValueError) whose message names the path and what to do.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import stat
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

MAX_JSON_DEPTH = 64
"""Deepest nesting of arrays and objects accepted in a JSON file (ecorl writes at most 6)."""
MAX_TEXT_BYTES = 256 << 20
"""Largest text file (config.json, metrics.csv, done.json, ...) read."""
NPY_KINDS = "biufcU"
"""Array kinds an ``.npy`` member may hold (no objects, no raw bytes, no structured records)."""
MAX_NPY_HEADER = 10_000
"""Largest ``.npy`` header read (numpy's own default limit)."""


class UnsafeFileError(ValueError):
    """A file or directory ecorl refuses to read or write (the message says why and what to do)."""


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a device"),
                       (stat.S_ISBLK, "a device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a symbolic link")):
        if test(mode):
            return name
    return "a file" if stat.S_ISREG(mode) else "not a regular file"


def open_regular(path: str | Path) -> BinaryIO:
    """Open ``path`` for reading if it is a regular file (not a symbolic link, FIFO, device or directory)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as err:
        if err.errno == 40:  # ELOOP: the last component is a symbolic link
            raise UnsafeFileError(f"{path} is a symbolic link; ecorl reads only regular files: replace the link "
                                  f"with the file itself") from None
        raise
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        raise UnsafeFileError(f"{path} is {_kind(info.st_mode)}, not a regular file; ecorl reads only regular "
                              f"files: move it away or replace it with the file ecorl wrote")
    fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    return os.fdopen(fd, "rb")


def regular_file(path: str | Path) -> Path:
    """``path`` if it is a regular file itself (not a symbolic link, FIFO, device or directory), for readers that
    open files by name (OpenCV's video decoder); else `UnsafeFileError`. A FIFO would block such a reader forever.
    """
    path = Path(path)
    mode = os.lstat(path).st_mode
    if not stat.S_ISREG(mode):
        raise UnsafeFileError(f"{path} is {_kind(mode)}, not a regular file; ecorl reads only regular files: move "
                              f"it away or replace it with the file ecorl wrote")
    return path


def no_link_below(root: str | Path, path: str | Path) -> Path:
    """``path`` if no component of it below ``root`` (``root`` itself excepted) is a symbolic link; else
    `UnsafeFileError`: a link inside a tree ecorl was handed could lead its reads or writes anywhere.
    """
    root, path = Path(root), Path(path)
    current = root
    for part in path.relative_to(root).parts:
        current = current / part
        if current.is_symlink():
            raise UnsafeFileError(f"{current} is a symbolic link inside {root}; ecorl follows no link inside a results "
                                  f"tree: replace it with the directory or file itself")
    return path


def read_bytes(path: str | Path, limit: int = MAX_TEXT_BYTES) -> bytes:
    """The bytes of the regular file ``path``, refusing one larger than ``limit``."""
    with open_regular(path) as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise UnsafeFileError(f"{path} is larger than {limit} bytes, more than ecorl ever writes there; it is "
                              f"not ecorl's file: move it away")
    return data


def read_text(path: str | Path, limit: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of the regular file ``path`` (see `read_bytes`)."""
    try:
        return read_bytes(path, limit).decode()
    except UnicodeDecodeError:
        raise UnsafeFileError(f"{path} is not UTF-8 text; it is not ecorl's file: move it away") from None


def _depth(value: Any) -> int:
    """Nesting depth of a parsed JSON value (iterative: no recursion limit is reached)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)):
            deepest = max(deepest, depth)
            stack.extend((child, depth + 1) for child in (node.values() if isinstance(node, dict) else node))
    return deepest


def loads_json(text: str | bytes, what: str) -> Any:
    """Parse JSON from ``what`` (a name for messages): nesting at most `MAX_JSON_DEPTH`, no number literal that
    overflows (``1e999``; Python writes NaN and infinities as ``NaN`` and ``Infinity``, which are kept).
    """
    def finite(token: str) -> float:
        value = float(token)
        if not math.isfinite(value):
            raise ValueError(f"the number {token} is not finite")
        return value

    try:
        value = json.loads(text, parse_float=finite)
    except RecursionError:
        raise UnsafeFileError(f"{what} nests deeper than {MAX_JSON_DEPTH} levels; it is not ecorl's JSON") from None
    except ValueError as err:  # JSONDecodeError, non-finite numbers, integers too long to convert
        raise UnsafeFileError(f"{what} is not valid JSON for ecorl ({' '.join(str(err).split())})") from None
    if _depth(value) > MAX_JSON_DEPTH:
        raise UnsafeFileError(f"{what} nests deeper than {MAX_JSON_DEPTH} levels; it is not ecorl's JSON")
    return value


def load_json(path: str | Path, limit: int = MAX_TEXT_BYTES) -> Any:
    """The JSON value in the regular file ``path`` (see `loads_json`)."""
    return loads_json(read_text(path, limit), str(path))


def read_npy(f: BinaryIO, limit: int, what: str) -> np.ndarray:
    """One ``.npy`` array from ``f``: header, dtype and size (at most ``limit`` bytes) checked before reading.

    Raises ValueError for an object or structured dtype, a size over the limit, or truncated data.
    """
    version = np.lib.format.read_magic(f)
    if version not in ((1, 0), (2, 0), (3, 0)):
        raise ValueError(f"{what} has .npy version {version}")
    reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    shape, fortran, dtype = reader(f, max_header_size=MAX_NPY_HEADER)
    if dtype.kind not in NPY_KINDS or dtype.hasobject or dtype.names is not None or dtype.subdtype is not None \
            or dtype.byteorder not in "=|":
        raise ValueError(f"{what} holds {dtype} values, not plain numbers or text in this machine's byte order")
    nbytes = math.prod(shape) * dtype.itemsize
    if nbytes > limit:
        raise ValueError(f"{what} declares shape {shape} of {dtype} ({nbytes} bytes), more than the {limit} bytes "
                         f"it may hold")
    buf = np.empty(nbytes, dtype=np.uint8)
    view, pos = memoryview(buf), 0
    while pos < nbytes:
        chunk = f.read(min(1 << 24, nbytes - pos))
        if not chunk:
            raise ValueError(f"{what} is truncated")
        view[pos:pos + len(chunk)] = chunk
        pos += len(chunk)
    return buf.view(dtype).reshape(shape, order="F" if fortran else "C")


def real_dir(path: str | Path) -> Path:
    """Create ``path`` (and its parents) if needed; refuse it if it is a symbolic link or not a directory."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:  # a file, or a link to nothing: refused below
        pass
    mode = os.lstat(path).st_mode
    if stat.S_ISLNK(mode):
        raise UnsafeFileError(f"{path} is {_kind(mode)}, not a directory; ecorl writes only into real directories "
                              f"(a link could send its files elsewhere): point --out at the real directory")
    if not stat.S_ISDIR(mode):
        raise UnsafeFileError(f"{path} is {_kind(mode)}, not a directory; point --out at a directory")
    return path
