"""Imports deferred to first use, so that a command's start-up (``strol-bench --help``) or
importing a package (``strol_gym.envs.robot``) loads no heavy stack it does not need."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from types import ModuleType
from typing import Any


def exports(package: str, public: dict[str, str]) -> Callable[[str], object]:
    """A package's module ``__getattr__``: each name in ``public`` (name → module) loads its
    module on first use; any other name is an AttributeError."""

    def __getattr__(name: str) -> object:
        if name in public:
            return getattr(importlib.import_module(public[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__


class LazyModule:
    """Stands for the module ``name``, imported on the first attribute read (after ``before``,
    e.g. choosing matplotlib's backend). For module-level names of heavy stacks used only
    inside functions: ``sps = LazyModule("scipy.stats")``."""

    def __init__(self, name: str, before: Callable[[], object] | None = None) -> None:
        self._name = name
        self._before = before
        self._module: ModuleType | None = None

    def __getattr__(self, attr: str) -> Any:
        if self._module is None:
            if self._before is not None:
                self._before()
            self._module = importlib.import_module(self._name)
        return getattr(self._module, attr)

    def __repr__(self) -> str:
        state = "loaded" if self._module is not None else "not loaded yet"
        return f"<LazyModule {self._name!r} ({state})>"
