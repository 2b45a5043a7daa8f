"""Writing a file all or nothing, and errors that name the file.

A temporary beside the target, fsync'ed, then ``os.replace``: after a crash or a full disk the
target holds the old bytes or the new ones, never a part. The benchmark's results folders and
the ĝ checkpoints (weights and sidecar, renamed together) write through here.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any


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


def host() -> str:
    """This machine's name as locks and temporary names record it."""
    return socket.gethostname().replace("/", "_") or "localhost"


def temp_tag() -> str:
    """``host-pid``: the part of a temporary file's name that says who wrote it, so that the
    next holder of a folder can tell a dead writer's leftovers from a live writer's file."""
    return f"{host()}-{os.getpid()}"


def temp_beside(path: Path, write: Callable[[Path], object]) -> Path:
    """``write(tmp)`` into a temporary file beside ``path``, fsync'ed; returns the temporary
    (the caller renames it, with others if files must appear together). On any error the
    temporary is removed and the OSError names ``path``."""
    path = Path(path)
    fd, name = tempfile.mkstemp(
        dir=path.parent, prefix=f".{path.name}.{temp_tag()}.", suffix=".tmp"
    )
    os.close(fd)
    tmp = Path(name)
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


def write_atomic(path: Path, write: Callable[[Path], object]) -> Path:
    """``write(tmp)``, then rename the temporary onto ``path``: all or nothing."""
    tmp = temp_beside(path, write)
    try:
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return Path(path)


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
