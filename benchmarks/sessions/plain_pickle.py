"""Read a pickle that may hold only numpy arrays inside lists, dicts and numbers.

The authors' user-study logs are pickles, and a pickle can name any callable for the loader to
run. This reader admits exactly what numpy needs to rebuild a plain numeric ndarray
(``_reconstruct``, ``ndarray``, ``dtype``, ``scalar``) and refuses every other global, so a
file naming ``os.system`` is an error, not a command. Even the admitted names never reach
numpy's own constructors: they build stand-ins that check the dtype (numbers only: bool, int,
uint, float) and that shape × item size equals the bytes the file carries *before* any array is
allocated, and the file's size is checked before it is read.
"""

from __future__ import annotations

import io
import math
import pickle
from pathlib import Path
from typing import Any, Literal

import numpy as np

from strol_gym.files import read_regular

MAX_FILE_BYTES = 256 * 2**20
"""The largest pickle read (the authors' largest is ~0.2 MB)."""
MAX_ARRAY_ITEMS = 10_000_000
"""The most elements one array may hold."""
MAX_NODES = 1_000_000
"""The most values (arrays, lists, dicts, numbers, strings) a pickle's tree may hold, counting
a shared one each time it is referenced (an authors' log holds a few thousand)."""
_KINDS = "biuf"
"""numpy dtype kinds admitted: bool, signed and unsigned integers, floats."""
_NUMPY_MODULES = ("numpy", "numpy.core.multiarray", "numpy._core.multiarray")


class PickleRefused(ValueError):
    """A pickle holding something besides numeric arrays, lists, dicts and numbers."""


class _DType:
    """Stand-in for ``numpy.dtype(spec, align, copy)``: keeps the spec until BUILD sets the
    byte order, then checks it is a plain numeric dtype."""

    def __init__(self, spec: Any, *_: Any) -> None:
        if not isinstance(spec, str) or len(spec) > 8:
            raise PickleRefused(f"dtype spec {spec!r} is not a numeric type code")
        self.spec = spec
        self.order: Literal["<", ">", "|", "="] = "|"

    def __setstate__(self, state: Any) -> None:
        if not isinstance(state, tuple) or len(state) < 2 or state[1] not in "<>|=":
            raise PickleRefused("a dtype with a structured or unknown state")
        if len(state) > 2 and any(s is not None for s in state[2:5]):
            raise PickleRefused("a structured dtype (fields or sub-arrays)")
        self.order = state[1]

    def resolve(self) -> np.dtype:
        try:
            dt = np.dtype(self.spec)
        except TypeError:
            raise PickleRefused(f"dtype {self.spec!r} is not a numeric type") from None
        if dt.kind not in _KINDS or dt.fields is not None or dt.subdtype is not None:
            raise PickleRefused(f"dtype {dt} is not a plain numeric type")
        return dt.newbyteorder(self.order) if self.order in "<>" else dt


class _Array:
    """Stand-in for ``_reconstruct(ndarray, ...)``: BUILD hands it (version, shape, dtype,
    fortran, bytes), checked before anything is allocated."""

    def __init__(self, cls: Any = None, *_: Any) -> None:
        if cls is not _NDARRAY:
            raise PickleRefused("_reconstruct of something other than numpy.ndarray")
        self.array: np.ndarray | None = None

    def __setstate__(self, state: Any) -> None:
        if not isinstance(state, tuple) or len(state) != 5:
            raise PickleRefused("an ndarray state that is not (version, shape, dtype, order, data)")
        _, shape, dtype, fortran, raw = state
        if not isinstance(dtype, _DType):
            raise PickleRefused("an ndarray whose dtype is not a plain numeric type")
        dt = dtype.resolve()
        ok = isinstance(shape, tuple) and len(shape) <= 8
        ok = ok and all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in shape)
        if not ok:
            raise PickleRefused(f"an ndarray shape {shape!r} that is not a tuple of sizes")
        items = math.prod(shape)
        if items > MAX_ARRAY_ITEMS:
            raise PickleRefused(f"an ndarray of {items} elements (at most {MAX_ARRAY_ITEMS})")
        if not isinstance(raw, bytes | bytearray) or len(raw) != items * dt.itemsize:
            raise PickleRefused(f"an ndarray of shape {shape} whose data is not its {dt} bytes")
        flat = np.frombuffer(bytes(raw), dtype=dt).astype(dt.newbyteorder("="))
        self.array = flat.reshape(shape, order="F" if fortran else "C")


def _scalar(dtype: Any, raw: Any = b"") -> int | float | bool:
    """Stand-in for ``numpy.core.multiarray.scalar``: a numeric scalar as a Python number."""
    if not isinstance(dtype, _DType):
        raise PickleRefused("a numpy scalar whose dtype is not a plain numeric type")
    dt = dtype.resolve()
    if not isinstance(raw, bytes) or len(raw) != dt.itemsize:
        raise PickleRefused(f"a numpy scalar of {dt} whose data is not {dt.itemsize} bytes")
    return np.frombuffer(raw, dtype=dt)[0].item()


class _NDArrayName:
    """What the name ``numpy.ndarray`` resolves to: only ``_reconstruct`` may take it."""


_NDARRAY = _NDArrayName()
_ADMITTED: dict[str, Any] = {
    "_reconstruct": _Array,
    "ndarray": _NDARRAY,
    "dtype": _DType,
    "scalar": _scalar,
}


class _Unpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if module in _NUMPY_MODULES and name in _ADMITTED:
            if (name == "ndarray" or name == "dtype") != (module == "numpy"):
                raise PickleRefused(f"global {module}.{name}")
            return _ADMITTED[name]
        raise PickleRefused(f"global {module}.{name}")

    def persistent_load(self, pid: Any) -> Any:
        raise PickleRefused("a persistent reference")


class _Plain:
    """The loaded tree with stand-ins replaced by arrays; anything else refused.

    An object the pickle references twice (through its memo) is converted once and stays
    shared, and the tree's size *as a reader walks it* (every reference counted, a shared list
    as often as it is referenced) is held to :data:`MAX_NODES`: 30 nested levels of
    ``[prev, prev]`` fit in 309 bytes and unfold to 2³⁰ leaves.
    """

    def __init__(self, budget: int) -> None:
        self.budget = budget
        self.done: dict[int, tuple[Any, int]] = {}  # id -> (converted, walked size)
        self.keep: list[Any] = []  # the originals, alive while their ids are keys

    def __call__(self, value: Any, depth: int = 0) -> tuple[Any, int]:
        if depth > 32:
            raise PickleRefused("nesting deeper than 32 levels")
        if isinstance(value, list | tuple | dict | _Array) and id(value) in self.done:
            return self.done[id(value)]
        if isinstance(value, _Array):
            if value.array is None:
                raise PickleRefused("an ndarray without data")
            out: Any
            out, size = value.array, 1
        elif isinstance(value, list | tuple):
            out, size = [], 1
            for v in value:
                item, n = self(v, depth + 1)
                out.append(item)
                size = self._add(size, n)
        elif isinstance(value, dict):
            if not all(isinstance(k, str | int) for k in value):
                raise PickleRefused("a dict with keys other than strings and integers")
            out, size = {}, 1
            for k, v in value.items():
                out[k], n = self(v, depth + 1)
                size = self._add(size, n)
        elif value is None or isinstance(value, bool | int | float | str):
            return value, 1
        else:
            raise PickleRefused(f"a {type(value).__name__} (only arrays, lists, dicts and numbers)")
        self.done[id(value)] = (out, size)
        self.keep.append(value)
        return out, size

    def _add(self, size: int, n: int) -> int:
        size += n
        if size > self.budget:
            raise PickleRefused(
                f"more than {self.budget:,} values once shared references are followed "
                "(a pickle that unfolds as it is read)"
            )
        return size


def load_plain_pickle(
    path: str | Path, max_bytes: int = MAX_FILE_BYTES, max_nodes: int = MAX_NODES
) -> Any:
    """The content of the pickle at ``path``: numpy arrays in lists and dicts, numbers, strings.

    Raises :class:`PickleRefused` (a ValueError naming the file) for anything else, for a file
    that is not a regular file or is larger than ``max_bytes``, for a tree of more than
    ``max_nodes`` values (:class:`_Plain`), or for a damaged pickle. Nothing in the file is
    ever called.
    """
    path = Path(path)
    try:
        raw = read_regular(path, max_bytes, "pickle")
    except OSError as e:
        raise PickleRefused(f"{path}: cannot read ({e.strerror or e})") from None
    except ValueError as e:
        raise PickleRefused(str(e)) from None
    try:
        return _Plain(max_nodes)(_Unpickler(io.BytesIO(raw)).load())[0]
    except MemoryError:
        raise PickleRefused(f"{path}: refused: too large to hold in memory") from None
    except PickleRefused as e:
        raise PickleRefused(f"{path}: refused: {e}") from None
    except RecursionError:
        raise PickleRefused(f"{path}: refused: nested too deeply") from None
    except Exception as e:  # a damaged pickle fails in many ways; none of them runs code
        raise PickleRefused(f"{path}: not a readable pickle ({type(e).__name__}: {e})") from None


__all__ = ["MAX_FILE_BYTES", "MAX_NODES", "PickleRefused", "load_plain_pickle"]
