"""mkdocs hooks: what the site generates rather than copies.

- The API reference reads `strol_gym.wrappers` and `strol_gym.benchmarks` under their import
  names from a tree of symlinks (`.ci/static_tree.py`) laid out here, so a plain
  `mkdocs build --strict` works from a clean checkout (no environment variable to set).
- A page's marker line `<!-- generated: KIND -->` is replaced by a table built from the live
  registries (`learners`, `humans`, `envs`) or by the CLI's own argparse help (`cli`), so the
  reference pages cannot drift from the code.
"""

from __future__ import annotations

import atexit
import importlib.util
import inspect
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Any

from mkdocs.plugins import event_priority

ROOT = Path(__file__).resolve().parent.parent
MARKER = re.compile(r"^<!-- generated: ([a-z-]+) -->$", re.M)


def _static_tree() -> Path:
    spec = importlib.util.spec_from_file_location("static_tree", ROOT / ".ci" / "static_tree.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    dest = Path(tempfile.mkdtemp(prefix="strol-docs-tree-"))
    atexit.register(shutil.rmtree, dest, ignore_errors=True)
    return Path(module.build(dest))


@event_priority(100)  # before mkdocstrings' own on_config, which builds the handler
def on_config(config: Any) -> Any:
    """Point mkdocstrings' python handler at the import-name tree."""
    handlers = config["plugins"]["mkdocstrings"].config["handlers"]
    handlers.setdefault("python", {})["paths"] = [str(_static_tree())]
    return config


def first_sentence(obj: Any, width: int = 140) -> str:
    """The first sentence of an object's docstring, on one line, pipes escaped."""
    doc = " ".join((inspect.getdoc(obj) or "").split())
    end = r"(?<!\beq\.)(?<!\be\.g\.)(?<!\bi\.e\.)(?<!\bal\.)(?<=[.!?])\s"  # not "et al. "
    first = re.split(end, doc, maxsplit=1)[0]
    first = first.replace("``", "`").replace("|", "\\|")
    return first if len(first) <= width else first[: width - 1] + "…"


def learners_table() -> str:
    """Every registered learner: name, how tables spell it, where it lives, what it does."""
    from strol_gym.learners.registry import _REGISTRY, LEARNERS, display_name

    rows = ["| name | in tables | defined in | what it is |", "|---|---|---|---|"]
    for name in LEARNERS.names():
        spec = _REGISTRY.get(name)
        where = f"`{spec}`" if isinstance(spec, str) else ""
        rows.append(
            f"| `{name}` | {display_name(name)} | {where} | {first_sentence(LEARNERS.get(name))} |"
        )
    return "\n".join(rows)


def humans_table() -> str:
    """Every registered human model: name and the first sentence of its docstring."""
    from strol_gym.humans import HUMANS

    rows = ["| name | what it is |", "|---|---|"]
    for name in HUMANS.names():
        piece = HUMANS.get(name)
        rows.append(f"| `{name}` | {first_sentence(getattr(piece, 'model_class', piece))} |")
    return "\n".join(rows)


def envs_table() -> str:
    """Every registered env id: entry point, vector entry point, episode length."""
    from strol_gym.registration import ENV_SPECS

    rows = ["| id | class | vector class | steps per episode |", "|---|---|---|---|"]
    for env_id, spec in ENV_SPECS.items():
        vector = spec.get("vector_entry_point")
        rows.append(
            f"| `{env_id}` | `{spec['entry_point']}` | {f'`{vector}`' if vector else '—'} "
            f"| {spec['max_episode_steps']} |"
        )
    return "\n".join(rows)


def cli_reference() -> str:
    """Each `strol-bench` subcommand's argparse help, under its own heading."""
    from strol_gym.benchmarks.cli import build_parser

    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal: a fixed width, same page
    try:
        parser = build_parser()
        return _cli_help(parser)
    finally:
        if columns is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = columns


def _cli_help(parser: Any) -> str:
    import argparse

    parts = ["```text", parser.format_help().rstrip(), "```"]
    for action in parser._actions:  # argparse keeps its subparsers here and nowhere public
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                parts += ["", f"## `strol-bench {name}`", "", "```text"]
                parts += [sub.format_help().rstrip(), "```"]
    return "\n".join(parts)


GENERATORS = {
    "learners": learners_table,
    "humans": humans_table,
    "envs": envs_table,
    "cli": cli_reference,
}


def render(markdown: str) -> str:
    """The page with each marker replaced by its generated text; an unknown kind is an error."""

    def one(match: re.Match[str]) -> str:
        kind = match.group(1)
        if kind not in GENERATORS:
            raise ValueError(f"unknown generated block {kind!r}; known: {sorted(GENERATORS)}")
        return GENERATORS[kind]()

    return MARKER.sub(one, markdown)


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    return render(markdown)
