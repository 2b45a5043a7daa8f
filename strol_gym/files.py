"""Writing a file all or nothing, and errors that name the file.

A temporary beside the target, fsync'ed, then ``os.replace``: after a crash or a full disk the
target holds the old bytes or the new ones, never a part. The benchmark's results folders and
the ĝ checkpoints (weights and sidecar, renamed together) write through here.

Only regular files are replaced, and only regular files are read: a path that names a device,
a FIFO, a socket, a directory or (for a write) a symbolic link is refused, naming it
(:class:`NotAFile`). Renaming onto ``/dev/full`` would turn the device node into our file, and
reading a FIFO blocks until someone writes to it, maybe forever.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import stat
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TextIO


@contextlib.contextmanager
def naming_file(path: Path) -> Iterator[None]:
    """Re-raise an OSError that names no file (a full disk: "[Errno 28] No space left on
    device") with ``path``, so the error says which file could not be written."""
    try:
        yield
    except OSError as e:
        if e.filename is not None or e.errno is None:
            raise
        raise OSError(e.errno, f"cannot write it: {e.strerror}", str(path)) from None


class NotAFile(OSError, ValueError):
    """A path that is not a regular file where one is read or replaced; the message names it.
    An OSError (a path we cannot use) and a ValueError (bad input), as callers catch either."""


def kind_of(mode: int) -> str:
    """What a file of ``mode`` (``st_mode``) is, in words."""
    for test, words in (
        (stat.S_ISLNK, "a symbolic link"),
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return words
    return "a regular file" if stat.S_ISREG(mode) else "not a regular file"


def check_output(path: str | os.PathLike[str], what: str = "output") -> Path:
    """``path`` if nothing is there or a regular file (which a write may replace); else
    :class:`NotAFile` naming it: a device, FIFO, socket, directory or symbolic link is never
    replaced by a file (nor written through)."""
    path = Path(path)
    try:
        mode = os.lstat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):  # nothing there (the folder's own check
        return path  # says why it cannot be made)
    if not stat.S_ISREG(mode):
        raise NotAFile(
            f"{what} {path} is {kind_of(mode)}, not a regular file: refusing to replace it "
            "(remove it or name another path)"
        )
    return path


def check_input(path: str | os.PathLike[str], what: str = "input") -> Path:
    """``path`` if it is a regular file (a symbolic link to one is followed), else
    :class:`NotAFile` naming it (a FIFO, a device, a socket, a directory), or the OSError of a
    missing file. For readers that open a file by name (HDF5, torch); readers of bytes use
    :func:`read_regular`, which checks the file it opened."""
    path = Path(path)
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        raise NotAFile(f"{what} {path} is {kind_of(mode)}, not a regular file: refused")
    return path


@contextlib.contextmanager
def open_regular(path: str | os.PathLike[str], what: str = "input") -> Iterator[Any]:
    """``path`` opened for reading in binary, if it is a regular file: opened without blocking
    (a FIFO's open would wait for a writer) and checked on the descriptor itself, so nothing
    can be swapped in between the check and the read. :class:`NotAFile` names it otherwise."""
    path = Path(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise NotAFile(f"{what} {path} is {kind_of(mode)}, not a regular file: refused")
        os.set_blocking(fd, True)
        f = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    with f:
        yield f


def read_regular(
    path: str | os.PathLike[str], max_bytes: int | None = None, what: str = "input"
) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_regular`); with ``max_bytes``, a
    longer file is a ValueError naming it, found before it is read whole."""
    with open_regular(path, what) as f:
        if max_bytes is None:
            return f.read()
        too_large = ValueError(f"{what} {path}: larger than {max_bytes:,} bytes (refused)")
        if os.fstat(f.fileno()).st_size > max_bytes:
            raise too_large
        parts, total = [], 0
        while chunk := f.read(min(READ_CHUNK, max_bytes + 1 - total)):  # a buffer of what is
            parts.append(chunk)  # there, not of the cap (read(n) allocates n bytes at once)
            total += len(chunk)
            if total > max_bytes:
                raise too_large
    return b"".join(parts)


READ_CHUNK = 1 << 20
"""Bytes per read of :func:`read_regular` under a cap."""


def host() -> str:
    """This machine's name as locks and temporary names record it."""
    return socket.gethostname().replace("/", "_") or "localhost"


def temp_tag() -> str:
    """``host-pid``: the part of a temporary file's name that says who wrote it, so that the
    next holder of a folder can tell a dead writer's leftovers from a live writer's file."""
    return f"{host()}-{os.getpid()}"


def _new_temp(path: Path) -> Path:
    """An empty temporary file beside ``path`` (named for its writer: ``temp_tag``)."""
    fd, name = tempfile.mkstemp(
        dir=path.parent, prefix=f".{path.name}.{temp_tag()}.", suffix=".tmp"
    )
    os.close(fd)
    return Path(name)


def temp_beside(path: Path, write: Callable[[Path], object]) -> Path:
    """``write(tmp)`` into a temporary file beside ``path``, fsync'ed; returns the temporary
    (the caller renames it, with others if files must appear together). On any error the
    temporary is removed and the OSError names ``path``. A ``path`` that is not a regular
    file (:func:`check_output`) is refused before anything is written."""
    path = check_output(path)
    tmp = _new_temp(path)
    try:
        with naming_file(path):
            write(tmp)
            with open(tmp, "rb+") as f:
                os.fsync(f.fileno())
    except BaseException as e:
        tmp.unlink(missing_ok=True)
        if isinstance(e, Exception) and not isinstance(e, OSError):
            raise OSError(f"cannot write {path}: {' '.join(str(e).split())}") from None
        raise
    return tmp


@contextlib.contextmanager
def open_atomic(path: Path, newline: str | None = None) -> Iterator[TextIO]:
    """A text file (UTF-8) to write ``path`` through, all or nothing: a temporary beside it,
    renamed onto it when the with-block ends without an error (:func:`write_atomic`)."""
    path = check_output(path)
    tmp = _new_temp(path)
    try:
        with naming_file(path):
            with open(tmp, "w", newline=newline, encoding="utf-8") as f:
                yield f
                f.flush()
                os.fsync(f.fileno())
            replace_checked(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_atomic(path: Path, write: Callable[[Path], object]) -> Path:
    """``write(tmp)``, then rename the temporary onto ``path``: all or nothing. ``path`` must
    be absent or a regular file (:func:`check_output`), checked again just before the rename."""
    tmp = temp_beside(path, write)
    try:
        replace_checked(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return Path(path)


def replace_checked(tmp: Path, path: str | os.PathLike[str]) -> None:
    """``os.replace(tmp, path)`` where ``path`` is absent or a regular file (:func:`check_output`,
    checked just before the rename), else :class:`NotAFile` and ``tmp`` left to the caller."""
    os.replace(tmp, check_output(path))


def write_text_atomic(path: Path, text: str) -> Path:
    """``text`` (UTF-8) written all or nothing."""
    data = text.encode("utf-8")
    return write_atomic(path, lambda tmp: tmp.write_bytes(data))


def write_figure(fig: Any, path: Path, **kwargs: Any) -> Path:
    """A matplotlib figure saved all or nothing, its format from ``path``'s suffix."""
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    return write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, **kwargs))


def write_json_atomic(path: Path, obj: Any) -> Path:
    """``obj`` as JSON (indent 1, NaN allowed) written all or nothing."""
    data = json.dumps(obj, indent=1, allow_nan=True).encode()
    return write_atomic(path, lambda tmp: tmp.write_bytes(data))


MAX_JSON_DEPTH = 64
"""The deepest nesting of arrays and objects a JSON input may have (a cap, not a limit of
ours: every file and option this project writes nests fewer than 10 levels)."""


def loads_json(text: str | bytes, what: str, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """``json.loads`` for input from outside, with every failure a ValueError naming ``what``:
    bad JSON, bytes that are not UTF-8, huge integers, and nesting deeper than ``max_depth``
    (refused whether or not the parser's recursion would have coped)."""
    try:
        value = json.loads(text)
    except RecursionError:
        raise ValueError(f"{what}: JSON nested deeper than {max_depth} levels") from None
    except ValueError as e:  # JSONDecodeError, UnicodeDecodeError, an integer with 5000 digits
        raise ValueError(f"{what} must be JSON ({' '.join(str(e).split())[:200]})") from None
    stack: list[tuple[Any, int]] = [(value, 1)]
    while stack:
        v, depth = stack.pop()
        if isinstance(v, dict | list):
            if depth > max_depth:
                raise ValueError(f"{what}: JSON nested deeper than {max_depth} levels")
            stack.extend((c, depth + 1) for c in (v.values() if isinstance(v, dict) else v))
    return value
