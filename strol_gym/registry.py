"""One open registry of names -> pieces: learners, humans, Tasks and benchmark conditions.

Each kind of piece keeps its built-in table where it is defined (learners, humans and Tasks
here; env presets and conditions in the benchmark); a :class:`Registry` wraps that table and,
when built, joins the registries of this process (:func:`registries`). This module imports none
of them: a kind is known once the module defining it is imported. Wherever strol-gym accepts a
name it also accepts ``"module:attr"`` (imported on use), and a user adds a name with
``register(name, piece)``.

User entries must reach the benchmark's worker processes, which start fresh (spawn). So what
travels is a *spec*, a ``"module:attr"`` string a worker can import, never a closure:
:func:`user_specs` collects them (and says which cannot travel), :func:`install_specs`
registers them in a worker.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterable, Mapping
from typing import Any, Generic, TypeVar

from strol_gym import checks

T = TypeVar("T")

__all__ = [
    "Registry",
    "call_piece",
    "import_spec",
    "install_specs",
    "load_installed_plugins",
    "plugin_argument",
    "plugin_modules",
    "registered_name",
    "registries",
    "resolve",
    "resolve_logged",
    "spec_of",
    "user_specs",
]


def import_spec(spec: str, what: str = "piece") -> Any:
    """The object named by ``"module:attr"`` (``attr`` may be dotted), else ValueError."""
    module, sep, attr = spec.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"{what} {spec!r} must be a registered name or 'module:attr'")
    try:
        obj: Any = importlib.import_module(module)
        for part in attr.split("."):
            obj = getattr(obj, part)
    except SystemExit as e:  # a module that calls sys.exit on import must not end the caller
        raise ValueError(f"{what} {spec!r}: module {module!r} called sys.exit({e.code})") from e
    except Exception as e:
        raise ValueError(f"{what} {spec!r}: cannot import {attr!r} from {module!r} ({e})") from e
    return obj


def spec_of(obj: Any) -> str | None:
    """``"module:qualname"`` if importing it gives back ``obj`` (so a worker can), else None.

    Lambdas, closures and objects of an interactive session have no such spec. Objects of the
    script being run (``__main__`` with a file) do: spawned workers import that script too.
    """
    if isinstance(obj, str):
        return obj if ":" in obj else None
    module = getattr(obj, "__module__", None)
    qualname = getattr(obj, "__qualname__", None)
    if not module or not qualname or "<" in qualname:
        return None
    if module == "__main__" and not getattr(sys.modules.get("__main__"), "__file__", None):
        return None
    try:
        found = import_spec(f"{module}:{qualname}")
    except ValueError:
        return None
    return f"{module}:{qualname}" if found is obj else None


def _names(entry: Any, piece: Any) -> bool:
    """Whether a lazy ``"module:attr"`` entry names ``piece`` (without importing anything new)."""
    if not isinstance(entry, str) or isinstance(piece, str):
        return False
    module, _, attr = entry.partition(":")
    return getattr(piece, "__module__", None) == module and (
        getattr(piece, "__qualname__", None) == attr
    )


def _callable_check(kind: str, signature: str) -> Callable[[str, Any], None]:
    def check(name: str, piece: Any) -> None:
        checks.callable_arg(f"{kind} {name!r}", piece, signature, spec=True)

    return check


def call_piece(kind: str, spec: Any, factory: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """``factory(*args, **kwargs)`` for the piece named ``spec``; a TypeError from the call (a
    callable with another signature, such as ``os:system``) becomes a
    ``checks.ArgumentTypeError`` (a ValueError too: the CLI's exit 2) naming the spec and its
    kind, instead of a traceback from inside it."""
    try:
        return factory(*args, **kwargs)
    except checks.ArgumentTypeError:
        raise  # the piece was built and named a bad argument itself: its own words stand
    except TypeError as e:
        said = " ".join(str(e).split())[:200]
        raise checks.ArgumentTypeError(
            f"{kind} {spec!r} is not a {kind} strol-gym can build: calling it failed "
            f"(TypeError: {said})"
        ) from None


class Registry(Generic[T]):
    """Names -> pieces of one kind ``T``, over a built-in table (shared, not copied).

    An entry is the piece itself (a class, factory or object) or a lazy ``"module:attr"``
    string. ``get`` accepts a registered name or any ``"module:attr"`` and returns a ``T``
    (what a ``"module:attr"`` names is trusted to be one: ``check`` runs on registration).
    """

    def __init__(
        self,
        kind: str,
        table: dict[str, Any],
        *,
        check: Callable[[str, Any], None] | None = None,
        callable_as: str | None = None,
        hint: str = "",
        encode: Callable[[Any], Any] | None = None,
        decode: Callable[[Any], Any] | None = None,
        shared: bool = True,
    ) -> None:
        """``check(name, piece)`` raises on a bad piece; ``callable_as`` (a signature such as
        ``"(task) -> policy"``) is the common check that the piece is callable.
        ``shared``: the kind's user entries travel to worker processes (``user_specs``)."""
        self.kind = kind
        self.table: dict[str, T | str] = table
        self.builtin = tuple(table)
        if check is None and callable_as is not None:
            check = _callable_check(kind, callable_as)
        self._check = check
        self.hint = hint
        self.encode = encode
        self.decode = decode
        """Pieces that are plain data (env presets) travel as ``encode(piece)`` (JSON) and are
        rebuilt with ``decode``; every other piece travels as its ``"module:attr"``."""
        if shared:
            _KINDS[kind] = self

    def check(self, name: str, piece: Any) -> None:
        """Raise ValueError, naming ``name``, if ``piece`` is not a valid piece of this kind."""
        if self._check is not None:
            self._check(name, piece)

    def names(self) -> list[str]:
        """Registered names, built-ins first, in registration order."""
        return list(self.table)

    def __contains__(self, name: object) -> bool:
        return name in self.table

    def register(
        self, name: str, piece: T | str, *, replace: bool = False, builtin: bool = False
    ) -> None:
        """Add ``piece`` (or a ``"module:attr"`` string, imported on first use) as ``name``.
        ``builtin``: a piece the package ships (registered at its import), not the user's."""
        if not isinstance(name, str) or not name or ":" in name or "," in name:
            error = ValueError if isinstance(name, str) else checks.ArgumentTypeError
            raise error(
                f"{self.kind} name must be a non-empty string without ':' or ',', got {name!r}"
            )
        current = self.table.get(name)
        same = current is not None and (
            current is piece
            or _names(current, piece)
            or (self.decode is not None and type(current) is type(piece) and current == piece)
        )
        if same and name not in self.builtin:
            self.table[name] = piece  # the same piece again (e.g. a worker importing the module
            return  # behind a spec it was sent, which registers itself on import)
        if name in self.table and (not replace or name in self.builtin):
            raise ValueError(f"a {self.kind} named {name!r} is already registered")
        if isinstance(piece, str):
            if ":" not in piece:
                raise ValueError(
                    f"a lazy {self.kind} entry must look like 'module:attr', got {piece!r}"
                )
        else:
            self.check(name, piece)
        self.table[name] = piece
        if builtin:
            self.builtin = (*self.builtin, name)

    def unregister(self, name: str) -> None:
        """Remove a user entry (built-ins stay)."""
        if name not in self.table:
            raise ValueError(
                f"no {self.kind} named {name!r}; known {self.kind}s: {', '.join(self.table)}"
            )
        if name in self.builtin:
            raise ValueError(f"{name!r} is a built-in {self.kind} and cannot be removed")
        del self.table[name]

    def user_names(self) -> list[str]:
        return [n for n in self.table if n not in self.builtin]

    def get(self, spec: str) -> T:
        """The piece for a registered name or a ``"module:attr"``; ValueError listing names."""
        if not isinstance(spec, str):
            raise checks.ArgumentTypeError(
                f"{self.kind} must be a name or 'module:attr', got {spec!r}"
            )
        if spec not in self.table and ":" not in spec and load_installed_plugins():
            return self.get(spec)  # an installed plugin may have registered it
        if spec in self.table:
            entry = self.table[spec]
            return import_spec(entry, self.kind) if isinstance(entry, str) else entry
        if ":" in spec:
            return import_spec(spec, self.kind)
        raise ValueError(
            f"unknown {self.kind} {spec!r}; known {self.kind}s: {', '.join(self.table)}, "
            f"or 'module:attr'{self.hint}"
        )

    def name_of(self, piece: Any) -> str | None:
        """The registered name whose entry is ``piece`` (or lazily names it), else None;
        imports nothing new."""
        for name, entry in self.table.items():
            if entry is piece or _names(entry, piece):
                return name
        return None

    def check_name(self, spec: str) -> str:
        """``spec`` if ``get`` would find it (imports a ``module:attr``), else ValueError."""
        self.get(spec)
        return spec


_KINDS: dict[str, Registry[Any]] = {}
"""Every shared registry of this process, by kind (each joins when it is built)."""


def registries() -> dict[str, Registry[Any]]:
    """Every registry of this process by kind: learner, human, task, and the benchmark's env
    presets and conditions once it is imported."""
    return dict(_KINDS)


def resolve(kind: str, spec: str) -> Any:
    """The piece of ``kind`` named ``spec`` (a registered name or ``"module:attr"``)."""
    if kind not in _KINDS:
        raise ValueError(f"kind must be one of {list(_KINDS)}, got {kind!r}")
    return _KINDS[kind].get(spec)


def registered_name(obj: Any) -> str | None:
    """The registered name of ``obj`` in any registry (what files name pieces by), else None."""
    for reg in _KINDS.values():
        name = reg.name_of(obj)
        if name is not None:
            return name
    return None


def user_specs(
    used: Mapping[str, Iterable[str]] | None = None,
) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """The user entries as importable specs ``{kind: {name: "module:attr"}}``, and the names
    that cannot travel to another process (each as "kind 'name'").

    ``used`` limits the answer to the names a run uses (``{kind: names}``).
    """
    specs: dict[str, dict[str, str]] = {}
    stuck: list[str] = []
    for kind, reg in registries().items():
        wanted = None if used is None else set(used.get(kind, ()))
        for name in reg.user_names():
            if wanted is not None and name not in wanted:
                continue
            entry = reg.table[name]
            spec = reg.encode(entry) if reg.encode is not None else spec_of(entry)
            if spec is None:
                stuck.append(f"{kind} {name!r}")
            else:
                specs.setdefault(kind, {})[name] = spec
    return specs, stuck


def install_specs(specs: dict[str, dict[str, Any]], code: bool = True) -> None:
    """Register ``user_specs`` output in this process (a worker). A name this process already
    has is left as it is: a worker starts without them, and the parent keeps its own.
    ``code=False`` (specs read from a file): only the plain-data kinds (env presets); a
    ``module:attr`` is never registered, so nothing the file names can be imported later."""
    regs = registries()
    for kind, entries in specs.items():
        if kind not in regs:
            raise ValueError(f"unknown kind of piece {kind!r}; known: {list(regs)}")
        reg = regs[kind]
        if not code and reg.decode is None:
            continue
        for name, spec in entries.items():
            if name not in reg.table:
                reg.register(name, spec if reg.decode is None else reg.decode(spec))


PLUGIN_GROUP = "strol_gym.plugins"
"""The entry-point group of installed plugins: a package that declares
``[options.entry_points] strol_gym.plugins = mine = my_package.pieces`` is imported by
``strol-bench`` (and on the first unknown name) without ``--plugin``."""

_PLUGIN_MODULES: dict[str, str] = {}
"""Modules the user made available -> the ``--plugin`` argument that loads them again ("" for an
installed entry point, which needs none): the only modules whose ``module:attr`` data written by
someone else may name."""
_INSTALLED_LOADED = False


def load_installed_plugins() -> list[str]:
    """Import every installed ``strol_gym.plugins`` entry point once (they register their
    pieces); the modules imported. A plugin that fails to import is a ValueError naming it."""
    global _INSTALLED_LOADED
    if _INSTALLED_LOADED:
        return []
    _INSTALLED_LOADED = True
    from importlib.metadata import entry_points

    loaded = []
    for ep in entry_points(group=PLUGIN_GROUP):
        try:
            importlib.import_module(ep.module)
        except (Exception, SystemExit) as e:  # a user package may raise anything on import
            raise ValueError(
                f"installed plugin {ep.name!r} ({ep.value}, entry point group {PLUGIN_GROUP!r}) "
                f"failed to import: {type(e).__name__}: {e}"
            ) from e
        _PLUGIN_MODULES.setdefault(ep.module, "")
        loaded.append(ep.module)
    return loaded


def plugin_argument(obj: Any) -> str | None:
    """The ``--plugin`` argument that makes ``obj`` (a class or function of a plugin) available
    in a new process; None for strol-gym's own pieces and those of installed plugins."""
    module = getattr(obj, "__module__", None) or ""
    for name, how in _PLUGIN_MODULES.items():
        if module == name or module.startswith(name + "."):
            return how or None
    return None


def plugin_modules() -> frozenset[str]:
    """The modules imported as plugins in this process."""
    return frozenset(_PLUGIN_MODULES)


def resolve_logged(kind: str, spec: Any) -> Any:
    """The piece a file written elsewhere (a session log, a dataset) names, without importing.

    Such a file may name a registered piece, or a ``module:attr`` inside a module the user made
    available with ``--plugin``; anything else is refused, so reading data never runs code.
    """
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"the {kind} must be a registered name, got {spec!r}")
    reg = registries()[kind]
    if spec in reg:
        return reg.get(spec)
    module, sep, attr = spec.partition(":")
    if not sep:
        raise ValueError(
            f"unknown {kind} {spec!r}; known {kind}s: {', '.join(reg.names())} "
            "(a plugin that registers it is loaded with --plugin)"
        )
    trusted = any(module == m or module.startswith(m + ".") for m in _PLUGIN_MODULES)
    if not trusted or module not in sys.modules:
        raise ValueError(
            f"{kind} {spec!r} is not a registered name, and data may not import code; if you "
            f"trust module {module!r}, make it available with --plugin {module}"
        )
    obj: Any = sys.modules[module]
    try:
        for part in attr.split("."):
            obj = getattr(obj, part)
    except AttributeError:
        raise ValueError(f"{kind} {spec!r}: module {module!r} has no {attr!r}") from None
    return obj


def import_plugin(spec: str) -> None:
    """Import a module of user pieces (which registers them): a module name, or a ``.py`` file
    whose folder then joins ``sys.path`` (so worker processes import it by the same name)."""
    from pathlib import Path

    path = Path(spec)
    how = spec
    if spec.endswith(".py"):
        if not path.is_file():
            raise ValueError(f"plugin {spec!r}: no such file")
        how = str(path.resolve())
        folder = str(path.resolve().parent)
        if folder not in sys.path:
            sys.path.insert(0, folder)
        spec = path.stem
    try:
        importlib.import_module(spec)
    except SystemExit as e:
        raise ValueError(f"plugin {spec!r} called sys.exit({e.code}) on import") from e
    except Exception as e:  # a user module may raise anything on import
        raise ValueError(f"plugin {spec!r} failed to import: {type(e).__name__}: {e}") from e
    _PLUGIN_MODULES[spec] = how
