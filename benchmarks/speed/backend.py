"""Wall time of ``--backend ray`` against ``local`` with the same number of workers, on one config
(target: Ray at most 1.3x slower). Both run into fresh temporary folders, so nothing is resumed;
the Ray figure includes starting and stopping the local cluster, as a user of the CLI pays it.
The load average is printed beside the figures: on a shared machine they are noisy.

    python -m strol_gym.benchmarks.speed.backend [--env robot|highway] [--runs N] [--jobs N]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

from strol_gym.benchmarks.engine.config import paper_config
from strol_gym.benchmarks.engine.runner import run_benchmark

TARGET_RATIO = 1.3


def _timed(config, jobs: int, backend: str) -> float:
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        run_benchmark(config, out, jobs=jobs, quiet=True, backend=backend)
        return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m strol_gym.benchmarks.speed.backend")
    p.add_argument("--env", choices=("robot", "highway"), default="robot")
    p.add_argument("--runs", type=int, default=None, help="runs per condition (default: paper's)")
    p.add_argument("--jobs", type=int, default=2, help="workers for both backends (2)")
    args = p.parse_args(argv)
    config = paper_config([args.env], runs=args.runs)
    units = len(config.units())
    print(
        f"{args.env}: {len(config.experiments)} conditions x {config.experiments[0].runs} runs x "
        f"{len(config.learners)} learners, {units} units of {config.block} seeds"
    )
    walls = {}
    for backend in ("local", "ray"):
        load = os.getloadavg()[0]
        walls[backend] = _timed(config, args.jobs, backend)
        print(
            f"{backend:>5} --jobs {args.jobs}: {walls[backend]:.1f} s "
            f"(load average {load:.1f} before, {os.getloadavg()[0]:.1f} after)"
        )
    ratio = walls["ray"] / walls["local"]
    verdict = "meets" if ratio <= TARGET_RATIO else "misses"
    print(f"ray / local = {ratio:.2f} ({verdict} the target of at most {TARGET_RATIO}x)")


if __name__ == "__main__":
    main()
