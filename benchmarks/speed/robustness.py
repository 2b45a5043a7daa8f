"""Wall time of ``strol-bench robustness`` at its defaults (target on 2 cores: Robot ≤ 5 min),
the whole command: start-up, the runs, the tables and the heat map. Runs into a fresh temporary
folder, so nothing is resumed and nothing is kept. Prints the load average beside the figure,
and the CPU seconds of this process and its workers (on an idle machine, wall ≈ CPU / jobs).

    python -m strol_gym.benchmarks.speed.robustness [--env robot|highway] [--jobs N] [--runs N]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import resource
import tempfile
import time

from strol_gym.benchmarks.engine.runner import default_jobs
from strol_gym.benchmarks.experiments.base import load

TARGET_S = {"robot": 300.0}


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def main(argv: list[str] | None = None) -> None:
    from strol_gym.benchmarks.cli import main as cli

    p = argparse.ArgumentParser(prog="python -m strol_gym.benchmarks.speed.robustness")
    p.add_argument("--env", choices=("robot", "highway"), default="robot")
    p.add_argument("--jobs", type=int, default=default_jobs())
    p.add_argument("--runs", type=int, default=None, help="override the default runs per cell")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as out:
        cmd = ["robustness", "--env", args.env, "--out", out, "--jobs", str(args.jobs), "--quiet"]
        if args.runs is not None:
            cmd += ["--runs", str(args.runs)]
        before = load()
        c0, t0 = _cpu(), time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            status = cli(cmd)
        wall, cpu = time.perf_counter() - t0, _cpu() - c0
    if status:
        raise SystemExit(status)
    target = TARGET_S.get(args.env, float("nan")) if args.runs is None else float("nan")
    runs = "" if args.runs is None else f" --runs {args.runs}"
    print(
        f"strol-bench robustness --env {args.env}{runs} --jobs {args.jobs}: "
        f"{wall:.1f} s wall, {cpu:.1f} CPU s (idle estimate "
        f"{cpu / args.jobs:.0f} s); {before} before, {load()} after; target {target:g} s"
    )


if __name__ == "__main__":
    main()
