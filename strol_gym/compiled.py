"""Which implementation of the hot loops runs: the plain (numpy/Python) reference or compiled
kernels (numba, the optional ``[fast]`` extra: ``pip install strol-gym[fast]``).

Chosen once per process by the environment variable ``STROL_GYM_KERNELS``: ``plain``, ``fast``
(numba required) or ``auto`` (the default: fast when numba imports). Both give the same bytes
on one machine (tests/test_compiled.py); the plain path is the reference and the readable one.
Kernels compile on first use and are cached on disk beside their module (``cache=True``), so a
second process loads them instead of compiling.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, TypeVar

KERNELS_VAR = "STROL_GYM_KERNELS"
MODES = ("auto", "plain", "fast")

F = TypeVar("F", bound=Callable[..., Any])


def _numba() -> Any:
    """numba, or None where it is missing or fails to load (a numpy newer than it supports)."""
    try:
        import numba
    except Exception:  # ImportError, or llvmlite's OSError: either way, no compiled kernels
        return None
    return numba


def _mode() -> str:
    mode = os.environ.get(KERNELS_VAR, "auto").strip().lower() or "auto"
    if mode not in MODES:
        raise ValueError(f"{KERNELS_VAR} must be one of {', '.join(MODES)}, got {mode!r}")
    return mode


def _choose(mode: str) -> bool:
    """Whether the kernels run under ``mode``: loads numba (once per process) unless plain."""
    if mode == "plain":
        return False
    found = _numba() is not None
    if mode == "fast" and not found:
        raise ImportError(f"{KERNELS_VAR}=fast needs numba: pip install 'strol-gym[fast]'")
    return found


MODE = _mode()
FAST: bool | None = False if MODE == "plain" else None
"""Whether the compiled kernels run; None until first asked (numba loads then, not when
strol_gym is imported). Tests set it to compare both paths."""


def use_fast() -> bool:
    """Whether callers take the compiled kernels (read at each call: tests switch it)."""
    global FAST
    if FAST is None:
        FAST = _choose(MODE)
    return FAST


def kernels_in_use() -> str:
    """``"fast"`` or ``"plain"``: what runs now."""
    return "fast" if use_fast() else "plain"


def compiled(fn: F) -> F:
    """``fn`` compiled by numba (no fast-math: IEEE operations as written, so the same bits as
    the plain path's), cached on disk; ``fn`` itself when numba is missing (then nothing calls
    it: ``use_fast()`` is False)."""
    numba = _numba()
    if numba is None:
        return fn
    return numba.njit(cache=True, nogil=True)(fn)
