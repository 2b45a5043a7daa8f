"""Argument checks: one wording for every bad argument, from Python and from the command line.

Each check takes the argument's name and value and returns the value in the form the caller
keeps (a float, an int, a float64 array, the registered piece's name ...), or raises an error
that says ``"{name} must be {what is valid}, got {value!r}"``. The envs, humans, learners,
registries and the CLI's argument types (``strol_gym.benchmarks.args``, which turns these errors
into argparse's exit status 2) all call these, so a bad argument reads the same wherever it is
given.

A value of the wrong kind (a string, dict or object where a number or array is expected) raises
:class:`ArgumentTypeError`, a ``TypeError`` that is also a ``ValueError``: callers that caught
``ValueError`` for every bad argument (the CLI, the benchmark's config checks) still do.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import Any, cast

import numpy as np

__all__ = [
    "ArgumentTypeError",
    "array",
    "callable_arg",
    "cli_type",
    "fraction_of",
    "instance",
    "mapping",
    "name_in",
    "number",
    "space_shape",
    "vector",
]


class ArgumentTypeError(TypeError, ValueError):
    """An argument of the wrong kind; a ValueError too, as every bad argument was before."""


def _bad(name: str, what: str, value: object, kind: bool = False) -> Exception:
    msg = f"{name} must be {what}, got {value!r}"
    return ArgumentTypeError(msg) if kind else ValueError(msg)


def _num(v: float) -> str:
    """A bound as written: an int in full (1000000), a float short (1e+06, 0.5)."""
    return str(v) if isinstance(v, int) else f"{v:g}"


def _range(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    """The valid range in words: '> 0', '>= 1', 'in [0, 1]', 'in (0, 1]', or ''."""
    if low is not None and high is not None:
        lo, hi = _num(low), _num(high)
        return f"in {'(' if low_open else '['}{lo}, {hi}{')' if high_open else ']'}"
    if low is not None:
        return f"{'>' if low_open else '>='} {_num(low)}"
    if high is not None:
        return f"{'<' if high_open else '<='} {_num(high)}"
    return ""


def number(
    name: str,
    value: object,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    integer: bool = False,
    text: bool = False,
) -> float:
    """One finite number in the given range (an integral one if ``integer``); never a bool.

    ``text``: a numeric string ("0.1", as a command line or a JSON file gives it) is read as
    its number. Returns the value itself (an int stays an int), or a float for text.
    """
    rng = _range(low, high, low_open, high_open)
    # a number between two bounds is finite; 'finite' is said where a bound is missing
    kind = (
        "an integer"
        if integer
        else "a number"
        if low is not None and high is not None
        else "a finite number"
    )
    what = kind + (f" {rng}" if rng else "")
    num: Any = value
    if text and isinstance(value, str):
        try:
            num = int(value) if integer else float(value)
        except ValueError:
            raise _bad(name, what, value, kind=True) from None
    if isinstance(num, bool | np.bool_) or not isinstance(
        num, int | float | np.integer | np.floating
    ):
        raise _bad(name, what, value, kind=True)
    x = float(num)
    if (
        not math.isfinite(x)
        or (integer and x != int(x))
        or (low is not None and (x <= low if low_open else x < low))
        or (high is not None and (x >= high if high_open else x > high))
    ):
        raise _bad(name, what, value)
    return cast(float, num)  # as given: an int stays an int, a numpy scalar its type


def fraction_of(name: str, value: object, low: float, high: float, unit: str) -> float:
    """A number in [low, high] given in ``unit`` (e.g. noise as a fraction of the action
    bound), numeric strings accepted: the humans' σ, ε and β, from Python and the CLI alike."""
    rng = f"a number in [{low:g}, {high:g}]" + (f" ({unit})" if unit else "")
    try:
        return float(number(name, value, low=low, high=high, text=True))
    except ArgumentTypeError:
        raise _bad(name, rng, value, kind=True) from None
    except ValueError:
        raise _bad(name, rng, value) from None


def vector(name: str, value: object, n: int | None = None, *, finite: bool = True) -> np.ndarray:
    """``n`` numbers (any shape holding n; any count >= 1 if None) as a fresh float64 vector."""
    what = (f"{n} " if n is not None else "a list of ") + (
        "finite numbers" if finite else "numbers"
    )
    if isinstance(value, str | bytes | Mapping):
        raise _bad(name, what, value, kind=True)
    try:
        v = np.array(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise _bad(name, what, value, kind=True) from None
    if (v.shape != (n,) if n is not None else v.size < 1) or (finite and not np.isfinite(v).all()):
        raise _bad(name, what, value)
    return v


def _shape_words(shape: Sequence[int | None]) -> str:
    return (
        "("
        + ", ".join("n" if s is None else str(s) for s in shape)
        + ("," if len(shape) == 1 else "")
        + ")"
    )


def array(
    name: str,
    value: object,
    shape: Sequence[int | None] | None = None,
    *,
    dtype: type | np.dtype = np.float64,
    finite: bool = True,
    copy: bool = False,
) -> np.ndarray:
    """An array of ``dtype`` (float64 by default) of ``shape`` (None: any length on that axis;
    no ``shape``: any), finite numbers unless ``finite`` is False. Not a copy unless ``copy``."""
    kind = "finite numbers" if finite else "numbers"
    what = f"an array of {kind}" + (f" of shape {_shape_words(shape)}" if shape is not None else "")
    if isinstance(value, str | bytes | Mapping):
        raise _bad(name, what, value, kind=True)
    if (
        not (isinstance(value, np.ndarray) and value.dtype.kind in "biuf")
        and np.dtype(dtype).kind != "c"
        and np.iscomplexobj(cast(Any, value))
    ):  # a real dtype would drop the imaginary part without a word
        raise _bad(name, what.replace("numbers", "real numbers"), value, kind=True)
    try:
        a = np.array(value, dtype=dtype) if copy else np.asarray(value, dtype=dtype)
    except (TypeError, ValueError):
        raise _bad(name, what, value, kind=True) from None
    if shape is not None and (
        a.ndim != len(shape)
        or any(s is not None and s != k for s, k in zip(shape, a.shape, strict=True))
    ):
        raise ValueError(f"{name} must be {what}, got shape {a.shape}")
    if finite and a.dtype.kind in "fc" and not np.isfinite(a).all():
        raise ValueError(f"{name} must be {what}, got a NaN or inf")
    return a


def name_in(name: str, value: object, names: Collection[str], what: str = "") -> str:
    """One of ``names`` (``what``: how to say what they are, e.g. 'a learner name')."""
    if isinstance(value, str) and value in names:
        return value
    listed = ", ".join(map(str, names))
    raise _bad(
        name, f"{what + ' ' if what else ''}one of {listed}", value, kind=not isinstance(value, str)
    )


def callable_arg(name: str, value: object, signature: str = "", *, spec: bool = False) -> None:
    """A callable (described by ``signature``, e.g. '(task) -> policy'); ``spec``: or a
    'module:attr' string that names one."""
    if callable(value) or (spec and isinstance(value, str) and ":" in value):
        return
    what = "a callable" + (f" {signature}" if signature else "")
    raise _bad(name, what + (" or a 'module:attr' string" if spec else ""), value, kind=True)


def mapping(name: str, value: object, what: str = "a dict of keyword arguments") -> dict[str, Any]:
    """A dict with string keys (keyword arguments), as a fresh dict; None as {}."""
    if value is None:
        return {}
    if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
        raise _bad(name, what, value, kind=True)
    return dict(value)


def instance(name: str, value: object, types: type | tuple[type, ...], what: str) -> Any:
    """``value`` if it is one of ``types`` (``what`` says which in words)."""
    if not isinstance(value, types):
        raise _bad(name, what, value, kind=True)
    return value


def space_shape(name: str, space: Any) -> tuple[int, ...]:
    """The shape of a space that has one (a Box); gymnasium types ``Space.shape`` as optional."""
    shape = getattr(space, "shape", None)
    if shape is None:
        raise ArgumentTypeError(f"{name} must be a space with a shape (a Box), got {space!r}")
    return tuple(shape)


def cli_type(check: Callable[[str], Any]) -> Callable[[str], Any]:
    """An argparse type from a check of the command line's text: argparse turns the check's
    error into its usage line and exit status 2, with the same words as from Python."""
    import argparse

    def parse(text: str) -> Any:
        try:
            return check(text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    parse.__name__ = getattr(check, "__name__", "value")
    return parse
