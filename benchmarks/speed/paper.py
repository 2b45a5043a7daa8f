"""Wall time of the full paper comparison per env (targets on 2 cores: Robot ≤ 60 s, Highway
≤ 5 min). Runs into fresh temporary folders, so nothing is resumed and nothing is kept.

    python -m strol_gym.benchmarks.speed.paper [--env robot|highway|all] [--jobs N] [--runs N]
"""

from __future__ import annotations

import argparse
import tempfile
import time

from strol_gym.benchmarks.engine.config import paper_config
from strol_gym.benchmarks.engine.runner import default_jobs, run_benchmark

TARGETS_S = {"robot": 60.0, "highway": 300.0}


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m strol_gym.benchmarks.speed.paper")
    p.add_argument("--env", choices=("robot", "highway", "all"), default="all")
    p.add_argument("--jobs", type=int, default=default_jobs())
    p.add_argument("--runs", type=int, default=None, help="override the paper's run counts")
    args = p.parse_args(argv)
    envs = ["robot", "highway"] if args.env == "all" else [args.env]
    for env in envs:
        config = paper_config([env], runs=args.runs)
        n_episodes = sum(e.runs for e in config.experiments) * len(config.learners)
        with tempfile.TemporaryDirectory() as out:
            t0 = time.perf_counter()
            run_benchmark(config, out, jobs=args.jobs, quiet=True)
            wall = time.perf_counter() - t0
        target = TARGETS_S[env] if args.runs is None else float("nan")
        print(
            f"{env}: {len(config.learners)} learners x {len(config.experiments)} conditions x "
            f"{config.experiments[0].runs} runs = {n_episodes} episodes in {wall:.1f} s "
            f"with --jobs {args.jobs} ({1e3 * wall / n_episodes:.1f} ms/episode; "
            f"target {target:g} s)"
        )


if __name__ == "__main__":
    main()
