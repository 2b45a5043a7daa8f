"""The experiment template: what every ``strol-bench`` experiment shares.

An experiment is a subcommand that builds its configs from its arguments, runs them through the
one runner (or computes its own numbers), and leaves a table (CSV + markdown), a meta JSON and
plots in its results folder. :class:`BenchExperiment` owns that sequence: parse errors, the
folder, the table, the meta (package versions, git revision, load), the plots (unless
``--no-plots``) and what is printed. A subclass fills in the parts that differ:

- ``add_arguments(p)``: its options (``strol_gym.benchmarks.args`` has the shared ones);
- ``plan(args)``: the configs (a ``ValueError`` here is a usage error, exit status 2);
- ``execute(plan, args, out)``: run them and return an :class:`Outcome` (rows, markdown, meta);
- ``columns`` and ``plot(outcome, folder)``: its table's columns and figures.

An experiment registered with ``register_experiment`` (``strol_gym.benchmarks.experiments``)
becomes a subcommand of ``strol-bench``; a module passed to ``--plugin`` may register one.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

from strol_gym.benchmarks.args import plugin_option
from strol_gym.benchmarks.engine.conditions import env_preset
from strol_gym.benchmarks.engine.config import BenchConfig
from strol_gym.benchmarks.engine.kernels import float_kernels
from strol_gym.benchmarks.engine.results import (
    ResultsDir,
    git_revision,
    package_versions,
    write_csv,
    write_json_atomic,
)
from strol_gym.files import write_text_atomic


@dataclasses.dataclass
class Outcome:
    """What an experiment's ``execute`` hands back to the template."""

    folder: Path
    """Where the table, the meta and the plots go."""
    markdown: list[str]
    """Printed at the end; also the table's ``.md`` when the experiment has ``columns``."""
    rows: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    """The table's rows (written as ``<name>.csv`` when the experiment has ``columns``)."""
    meta: dict[str, Any] | None = None
    """The experiment's settings for ``<name>.json`` (None: no meta file)."""
    wall_line: str = ""
    """The wall-time line printed after the markdown."""
    notes: list[str] = dataclasses.field(default_factory=list)
    """Lines printed after the wall-time line (paths of the files written, ...)."""
    state: Any = None
    """Anything ``plot`` needs besides the rows."""


class BenchExperiment:
    """A ``strol-bench`` experiment (see the module docstring). Subclasses fill the hooks."""

    name: str = ""
    """The subcommand, and the stem of the table and meta files."""
    help: ClassVar[str] = ""
    """The subcommand's one-line help; by default the class docstring's first paragraph."""
    description: ClassVar[str] = ""
    """``--help``'s description; by default the rest of the class docstring."""
    columns: tuple[str, ...] = ()
    """The table's columns; empty when the experiment writes its own tables."""
    out_stem: ClassVar[str] = ""
    """The default results folder is ``results/<out_stem or name>-<env>``."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Help and description from the class docstring, unless the class sets them."""
        super().__init_subclass__(**kwargs)
        first, _, rest = inspect.cleandoc(cls.__doc__ or "").partition("\n\n")
        if first and "help" not in vars(cls):
            cls.help = " ".join(first.split())
        if rest and "description" not in vars(cls):
            cls.description = " ".join(rest.split())

    # ------------------------------------------------------------------ hooks
    def add_arguments(self, p: argparse.ArgumentParser) -> None:
        """The subcommand's options."""

    def plan(self, args: argparse.Namespace) -> Any:
        """The configs to run (ValueError: a usage error naming the argument)."""
        return None

    def execute(self, plan: Any, args: argparse.Namespace, out: Path) -> Outcome:
        """Run ``plan`` into ``out`` and collect the outcome."""
        raise NotImplementedError

    def plot(self, outcome: Outcome, folder: Path) -> list[Path]:
        """The experiment's figures, in ``folder`` (the results folder's ``plots/``)."""
        return []

    def default_out(self, args: argparse.Namespace) -> str:
        stem = self.out_stem or self.name
        env = getattr(args, "env", None)
        return f"results/{stem}-{env}" if env else f"results/{stem}"

    # ------------------------------------------------------------------ the template
    def add_parser(self, sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
        p = sub.add_parser(self.name, help=self.help, description=self.description or self.help)
        self.add_arguments(p)
        if "--plugin" not in p._option_string_actions:  # every experiment takes --plugin
            plugin_option(p)
        return p

    needs_own_out: bool = False
    """True for experiments that write their own files into ``--out`` (not a results folder of
    the runner there): a run's results folder is then refused, never mixed into."""

    def __call__(self, args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
        try:
            plan = self.plan(args)
        except ValueError as e:
            parser.error(str(e))
        out = Path(args.out or self.default_out(args))
        if self.needs_own_out and (out / "meta.json").exists():
            parser.error(
                f"--out {out} is a benchmark's results folder (it holds meta.json); {self.name} "
                "writes files of its own: choose another --out"
            )
        outcome = self.execute(plan, args, out)
        files: list[Path] = []
        if self.columns:
            files += write_table(
                outcome.folder, self.name, outcome.rows, self.columns, outcome.markdown
            )
        if outcome.meta is not None:
            write_meta(outcome.folder, self.name, {"preset": self.name, **outcome.meta})
        plots = [] if args.no_plots else self.plot(outcome, outcome.folder / "plots")
        print("\n".join(outcome.markdown))
        print(outcome.wall_line or f"\nresults in {outcome.folder}/")
        for line in outcome.notes:
            print(line)
        for f in [*files, *(p for p in plots if p.suffix == ".png")]:
            print(f"wrote {f}")
        return 0

    # ------------------------------------------------------------------ helpers
    @staticmethod
    def run(
        config: BenchConfig, out: Path, args: argparse.Namespace, *, reports: bool = True
    ) -> tuple[ResultsDir, Any, float]:
        """Run (or resume) ``config`` into ``out`` with the one runner; with ``reports``, write
        its standard tables (summary.md, summary.csv, stats.csv, …; figures are left to
        ``strol-bench report OUT``). Returns (folder, analysis or None, episodes' wall time s)."""
        from strol_gym.benchmarks.analysis.report import write_reports
        from strol_gym.benchmarks.engine.backends import backend_kwargs
        from strol_gym.benchmarks.engine.runner import default_jobs, run_benchmark

        jobs = getattr(args, "jobs", None) or default_jobs()
        t0 = time.perf_counter()
        backend = backend_kwargs(args) if hasattr(args, "backend") else {}
        rd = run_benchmark(config, out, jobs=jobs, quiet=args.quiet, force=args.force, **backend)
        wall = time.perf_counter() - t0
        analysis = write_reports(rd, plots=False)[0] if reports else None
        return rd, analysis, wall

    @staticmethod
    def wall(seconds: float, folder: Path) -> str:
        return f"\nwall time {seconds:.1f} s ({load()}); results in {folder}/"


def load() -> str:
    """The 1/5/15-minute load averages, for quoting beside a wall time."""
    try:
        return "load average " + ", ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "load average unknown"


def write_table(
    out: Path, stem: str, rows: Sequence[dict], columns: Sequence[str], markdown: Sequence[str]
) -> list[Path]:
    """``stem.csv`` (full precision) and ``stem.md`` (the given markdown lines) in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    csv_path = write_csv(out / f"{stem}.csv", rows, columns)
    md_path = out / f"{stem}.md"
    write_text_atomic(md_path, "\n".join(markdown) + "\n")
    return [csv_path, md_path]


def primary_metric(a: Any, env: str) -> str:
    """The env's primary metric where the analysis ``a`` has it, else the error ‖θ* − θ̂‖."""
    metric = env_preset(env).primary_metric
    return metric if metric in a.metrics_for(env) else "error"


def write_meta(out: Path, stem: str, meta: dict[str, Any]) -> Path:
    """``stem.json``: the experiment's own settings plus package versions, git revision, the
    floating-point kernels and the load."""
    out.mkdir(parents=True, exist_ok=True)
    full = {
        "tool": "strol-bench",
        **meta,
        "versions": package_versions(),
        "git": git_revision(),
        "kernels": float_kernels(),
        "load": load(),
    }
    path = out / f"{stem}.json"
    write_json_atomic(path, full)
    return path


def fmt_paper(v: float | None) -> str:
    """A value read off the paper's figure: "≈ v", or "—" when the paper has none."""
    return "—" if v is None else f"≈ {v:g}"


def small_figure(stem: Path) -> tuple[Any, Any]:
    """A one-panel figure for an experiment's plot, its folder made: (fig, ax)."""
    from strol_gym.benchmarks.analysis.plots import plt

    stem.parent.mkdir(parents=True, exist_ok=True)
    return plt.subplots(figsize=(4.8, 3.2))
