"""Old module paths of the envs, kept importable for one release after the move to subpackages
by simulator: importing one warns and gives the new module itself, so its names, private ones
included, and Minari headers or entry points that name the old path still resolve. Names use
``strol_gym.deprecation.moved``.
"""

from __future__ import annotations

import importlib
import sys
import warnings
from types import ModuleType

from strol_gym.deprecation import REMOVAL, moved


def alias(old: str, new: str) -> ModuleType:
    """Warn that ``old`` moved and put its new module in ``sys.modules`` under the old name.
    (Each old module names its new one itself: a table here would be an import of every env
    module from this one, which the package map forbids.)"""
    warnings.warn(
        f"{old} is now {new}; the old name goes in {REMOVAL}",
        DeprecationWarning,
        stacklevel=3,
    )
    module = importlib.import_module(new)
    sys.modules[old] = module
    return module


def warn_split(old: str, names: dict[str, str]) -> object:
    """The ``__getattr__`` of an old module split across new ones (``names``: name → its new
    module): warns on import, then each name resolves (with a warning) from its new module."""
    warnings.warn(
        f"{old} was split across strol_gym.envs.study; the old name goes in {REMOVAL}",
        DeprecationWarning,
        stacklevel=3,
    )
    return exports(old, {}, names)


def exports(package: str, public: dict[str, str], old: dict[str, str] | None = None):
    """A package's module ``__getattr__``: ``public`` names (name → module) load their module
    on first use, so importing the package imports no simulator; ``old`` names (what the old
    module of that name held, name → its new module) warn (``strol_gym.deprecation.moved``)."""
    aliases = moved(package, {name: f"{home}:{name}" for name, home in (old or {}).items()})

    def __getattr__(name: str) -> object:
        if name in public:
            return getattr(importlib.import_module(public[name]), name)
        return aliases(name)

    return __getattr__
