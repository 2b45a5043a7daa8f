"""The package map (docs/layout.md) enforced: every module sits in a layer, imports only from
lower layers or its own package, and no module reaches itself again, directly or through others.

The graph is read from the source, counting what an import really runs:

- every ``import`` statement, also those inside functions and methods (they run later, but a
  cycle hidden in a function is one module move away from a circular ImportError);
- ``from package import module`` (counts the module), ``from package import name`` (counts the
  package) and relative imports;
- string imports: ``importlib.import_module("a.b")`` and any other string literal naming a
  package module, bare or as a registry's ``"module:attr"`` entry (the registries load them);
- the parent packages an import runs: importing ``a.b.c`` runs ``a/__init__`` and
  ``a/b/__init__`` first, except those already running around the importer (its own parents).

Imports under ``if TYPE_CHECKING:`` are left out: they never run. Docstrings are not imports.
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {
    "strol_gym": "strol_gym",
    "strol_gym.wrappers": "wrappers",
    "strol_gym.benchmarks": "benchmarks",
    "lab": "lab",
}
BENCHMARK = "strol_gym.benchmarks"
LAB = "lab"
ROOTS = {"strol_gym", BENCHMARK}

# The layers, lowest first (docs/layout.md). A module belongs to the unit with the longest
# matching prefix; it may import its own unit and any unit of a lower layer, nothing else.
# Prefixes, not files: a unit's inner layout (envs/ by simulator or flat) is its own business.
LAYERS: list[tuple[str, ...]] = [
    ("strol_gym.checks",),
    (
        "strol_gym.registry",
        "strol_gym.provenance",
        "strol_gym.files",
        "strol_gym.limits",
        "strol_gym.lazy",
        "strol_gym.planning",
        "strol_gym.metrics",
        "strol_gym.compiled",
        "strol_gym.pcg64_fill",
    ),
    ("strol_gym.priors", "strol_gym.draws"),
    ("strol_gym.tasks",),
    ("strol_gym.humans",),
    ("strol_gym.learners",),
    ("strol_gym.envs",),
    ("strol_gym.wrappers",),
    ("strol_gym.registration", "strol_gym.analysis", "strol_gym.testing"),
    ("strol_gym",),
    ("strol_gym.benchmarks.engine",),
    ("strol_gym.benchmarks.analysis",),
    ("strol_gym.benchmarks.args",),
    ("strol_gym.benchmarks.experiments", "strol_gym.benchmarks.sessions"),
    ("strol_gym.benchmarks.train", "strol_gym.benchmarks.serve"),
    ("strol_gym.benchmarks.cli",),
    ("strol_gym.benchmarks.__main__", "strol_gym.benchmarks.speed"),
    ("strol_gym.benchmarks.examples",),
    ("strol_gym.benchmarks",),
    # the lab (not installed): it may use the benchmark and the library, nothing uses it; its
    # rooms, then the scripts at its top
    ("lab.speed", "lab.study", "lab.checks"),
    ("lab",),
]
# benchmarks/'s top level: the CLI and what only the CLI shares; everything else in a room.
BENCHMARK_TOP = {"__init__.py", "__main__.py", "args.py", "cli.py", "train.py"}
_NAME = re.compile(r"((?:strol_gym|lab)(?:\.\w+)*)(?::[\w.]+)?")


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Every module of the package, by its import name (setup.cfg's package_dir mapping)."""
    out: dict[str, Path] = {}
    for package, folder in PACKAGES.items():
        for path in sorted((root / folder).rglob("*.py")):
            rel = path.relative_to(root / folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            out[".".join([package, *parts])] = path
    return out


def parents(name: str) -> list[str]:
    """``a.b.c`` -> ``["a", "a.b"]``: the packages Python runs before the module."""
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def _type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
    )


def _docstring(node: ast.AST) -> bool:
    return (
        isinstance(node, ast.Expr)
        and isinstance(node.value, ast.Constant)
        and isinstance(node.value.value, str)
    )


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The package modules importing ``name`` runs, now or later (see the module docstring)."""
    is_pkg = path.name == "__init__.py"
    running = {name, *parents(name)}
    found: set[str] = set()

    def add(target: str) -> None:
        while target and target not in known:
            target = target.rpartition(".")[0]
        if target:
            found.update(t for t in (*parents(target), target) if t in known and t not in running)

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if _docstring(node):
            return
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = name if is_pkg else name.rpartition(".")[0]
                for _ in range(node.level - 1):
                    parent = parent.rpartition(".")[0]
                base = f"{parent}.{base}" if node.module else parent
            for alias in node.names:
                add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            m = _NAME.fullmatch(node.value)
            if m and m.group(1) in known:
                add(m.group(1))
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text(), filename=str(path)))
    return found


@functools.cache
def graph(root: Path = ROOT) -> dict[str, set[str]]:
    mods = modules(root)
    known = set(mods)
    return {name: imports(name, path, known) for name, path in mods.items()}


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(g.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            strong(v)
    return out


def unit(name: str) -> tuple[int, str] | None:
    """(layer, unit prefix) of a module: the longest matching prefix on the map, else None. A
    root package (``strol_gym``, ``strol_gym.benchmarks``) is its ``__init__`` alone."""
    best: tuple[int, str] | None = None
    for layer, prefixes in enumerate(LAYERS):
        for p in prefixes:
            inside = name == p or (p not in ROOTS and name.startswith(p + "."))
            if inside and (best is None or len(p) > len(best[1])):
                best = (layer, p)
    return best


def reachable(g: dict[str, set[str]], start: str) -> set[str]:
    seen: set[str] = set()
    todo = [start]
    while todo:
        for w in g.get(todo.pop(), ()):
            if w not in seen:
                seen.add(w)
                todo.append(w)
    return seen


# ---------------------------------------------------------------------------- the reader itself
def _tree(tmp: Path, files: dict[str, str]) -> dict[str, set[str]]:
    for rel, text in files.items():
        p = tmp / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    for folder in PACKAGES.values():
        (tmp / folder).mkdir(exist_ok=True)
    return graph(tmp)


def test_the_reader_sees_every_kind_of_import(tmp_path):
    g = _tree(
        tmp_path,
        {
            "strol_gym/__init__.py": "",
            "strol_gym/a/__init__.py": "from strol_gym.a import one\n",
            "strol_gym/a/one.py": "def f():\n    from strol_gym import b\n",
            "strol_gym/a/two.py": "from . import one\nfrom .one import f\n",
            "strol_gym/b/__init__.py": '"""Not an import: strol_gym.c"""\n',
            "strol_gym/b/x.py": 'import importlib\nimportlib.import_module("strol_gym.c")\n',
            "strol_gym/b/y.py": 'REG = {"k": "strol_gym.d:Thing"}\n',
            "strol_gym/b/z.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
            "    import strol_gym.c\n",
            "strol_gym/c.py": "",
            "strol_gym/d/__init__.py": "",
            "strol_gym/d/e.py": "import strol_gym.a.two\n",
        },
    )
    assert g["strol_gym.a.one"] == {"strol_gym.b"}  # function-level, from-package-import-module
    assert g["strol_gym.a.two"] == {"strol_gym.a.one"}  # relative, both forms
    assert g["strol_gym.b"] == set()  # a docstring is not an import
    assert g["strol_gym.b.x"] == {"strol_gym.c"}  # importlib
    assert g["strol_gym.b.y"] == {"strol_gym.d"}  # a registry's "module:attr"
    assert g["strol_gym.b.z"] == set()  # TYPE_CHECKING
    # the parent package an import runs (its own parents are already running)
    assert g["strol_gym.d.e"] == {"strol_gym.a", "strol_gym.a.two"}


def test_a_cycle_through_a_parent_package_and_a_function_is_found(tmp_path):
    """The shape of the cycle this test first missed: a Task's method imported the humans,
    whose module imported the Task's sibling, whose package __init__ imports the Task."""
    g = _tree(
        tmp_path,
        {
            "strol_gym/__init__.py": "",
            "strol_gym/tasks/__init__.py": "from strol_gym.tasks.highway import H\n",
            "strol_gym/tasks/base.py": "",
            "strol_gym/tasks/highway.py": "def f():\n    from strol_gym.humans import d\n",
            "strol_gym/humans/__init__.py": "from strol_gym.humans.choices import d\n",
            "strol_gym/humans/choices.py": "from strol_gym.tasks.base import T\n",
        },
    )
    assert cycles(g) == [
        [
            "strol_gym.humans",
            "strol_gym.humans.choices",
            "strol_gym.tasks",
            "strol_gym.tasks.highway",
        ]
    ]


def test_cycles_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


# ---------------------------------------------------------------------------- the package's map
def test_the_graph_sees_every_layer():
    g = graph()
    assert "strol_gym.benchmarks.engine.runner" in g and "strol_gym.wrappers" in g
    # an edge we know is there: the worker uses the learner registry
    assert "strol_gym.learners.registry" in g["strol_gym.benchmarks.engine.worker"]


def test_no_import_cycles():
    found = cycles(graph())
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)


def test_every_module_is_on_the_map():
    missing = sorted(m for m in graph() if unit(m) is None)
    assert not missing, f"modules on no layer of docs/layout.md: {missing}"


def test_imports_follow_the_map():
    g = graph()
    wrong = []
    for m, targets in g.items():
        here = unit(m)
        for t in targets:
            there = unit(t)
            if here and there and there[1] != here[1] and there[0] >= here[0]:
                wrong.append(f"{m} ({here[1]}) -> {t} ({there[1]})")
    assert not wrong, "imports against docs/layout.md's layers: " + "; ".join(sorted(wrong))


def test_the_core_never_reaches_the_benchmark():
    g = graph()
    wrong = sorted(
        f"{m} -> ... -> {t}"
        for m in g
        if not m.startswith((BENCHMARK, LAB))
        for t in reachable(g, m)
        if t.startswith(BENCHMARK)
    )
    assert not wrong, "the core imports the benchmark: " + "; ".join(wrong)


def test_nothing_installed_reaches_the_lab():
    g = graph()
    wrong = sorted(
        f"{m} -> ... -> {t}"
        for m in g
        if not m.startswith(LAB)
        for t in reachable(g, m)
        if t.startswith(LAB)
    )
    assert not wrong, "an installed module imports the lab: " + "; ".join(wrong)


def test_benchmark_top_level_holds_the_cli_only():
    top = {p.name for p in (ROOT / "benchmarks").glob("*.py")}
    assert top <= BENCHMARK_TOP, f"put {sorted(top - BENCHMARK_TOP)} in a room of benchmarks/"
