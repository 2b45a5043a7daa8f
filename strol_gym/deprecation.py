"""Old names that keep working for one release, with a DeprecationWarning when used.

A module that lost names assigns ``__getattr__ = moved(__name__, {"Old": "new.module:New"})``;
Python calls it only for names the module does not define, so the new names cost nothing and the
warning points at the caller's line. CHANGELOG.md lists every entry.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Mapping
from typing import Any

REMOVAL = "the next release"


def moved(module: str, names: Mapping[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` serving ``names``: old name -> ``"module:attr"`` of its new home."""

    def __getattr__(name: str) -> Any:
        target = names.get(name)
        if target is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        where, _, attr = target.partition(":")
        warnings.warn(
            f"{module}.{name} is now {where}.{attr}; the old name goes in {REMOVAL}",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module(where), attr)

    return __getattr__
