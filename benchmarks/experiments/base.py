"""What the experiment presets (changing, lambda, basin, confirm) share: running a config through
the one runner, option parsing, and writing a preset's own table (CSV + markdown) and meta JSON.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from strol_gym.benchmarks.config import BenchConfig
from strol_gym.benchmarks.results import (
    ResultsDir,
    git_revision,
    package_versions,
    write_csv,
    write_json_atomic,
)


def float_list(name: str, *, low: float = 0.0):
    """argparse type: comma-separated finite numbers >= ``low``, at least one."""

    def parse(text: str) -> list[float]:
        out = []
        for tok in (t.strip() for t in text.split(",")):
            try:
                v = float(tok)
            except ValueError:
                v = math.nan
            if not math.isfinite(v) or v < low:
                bound = "" if low == -math.inf else f" >= {low:g}"
                raise argparse.ArgumentTypeError(
                    f"{name} must be comma-separated finite numbers{bound}, got {tok!r}"
                )
            out.append(v)
        if not out:
            raise argparse.ArgumentTypeError(f"{name} must name at least one value")
        return out

    return parse


def finite(name: str, *, low: float | None = None):
    """argparse type: one finite number (>= ``low`` when given)."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            v = math.nan
        if not math.isfinite(v) or (low is not None and v < low):
            rng = "a finite number" + ("" if low is None else f" >= {low:g}")
            raise argparse.ArgumentTypeError(f"{name} must be {rng}, got {text!r}")
        return v

    return parse


def load() -> str:
    """The 1/5/15-minute load averages, for quoting beside a wall time."""
    try:
        return "load average " + ", ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "load average unknown"


def run_config(
    config: BenchConfig, out: Path, args: argparse.Namespace
) -> tuple[ResultsDir, Any, float]:
    """Run (or resume) ``config`` into ``out`` with the one runner, then write its standard
    tables (summary.md, summary.csv, stats.csv, …). The standard figures are left to
    ``strol-bench report OUT`` (they cost more than a small preset run); each preset draws its
    own. Returns (results folder, analysis, wall time of the episodes in s)."""
    from strol_gym.benchmarks.backends import backend_kwargs
    from strol_gym.benchmarks.report import write_reports
    from strol_gym.benchmarks.runner import default_jobs, run_benchmark

    jobs = getattr(args, "jobs", None) or default_jobs()
    t0 = time.perf_counter()
    backend = backend_kwargs(args) if hasattr(args, "backend") else {}
    rd = run_benchmark(config, out, jobs=jobs, quiet=args.quiet, force=args.force, **backend)
    wall = time.perf_counter() - t0
    analysis, _ = write_reports(rd, plots=False)
    return rd, analysis, wall


def write_table(
    out: Path, stem: str, rows: Sequence[dict], columns: Sequence[str], markdown: Sequence[str]
) -> list[Path]:
    """``stem.csv`` (full precision) and ``stem.md`` (the given markdown lines) in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    csv_path = write_csv(out / f"{stem}.csv", rows, columns)
    md_path = out / f"{stem}.md"
    md_path.write_text("\n".join(markdown) + "\n")
    return [csv_path, md_path]


def write_meta(out: Path, stem: str, meta: dict[str, Any]) -> Path:
    """``stem.json``: the preset's own settings plus package versions, git revision and load."""
    out.mkdir(parents=True, exist_ok=True)
    full = {
        "tool": "strol-bench",
        **meta,
        "versions": package_versions(),
        "git": git_revision(),
        "load": load(),
    }
    path = out / f"{stem}.json"
    write_json_atomic(path, full)
    return path


def fmt(v: float, digits: int = 3) -> str:
    """A table number: fixed digits, scientific for tiny non-zero values, 'n/a' for NaN."""
    if v is None or not math.isfinite(v):
        return "n/a"
    if v != 0 and abs(v) < 10 ** (-digits):
        return f"{v:.1e}"
    return f"{v:.{digits}f}"
