"""Do the study's H3 verdicts hold over disjoint sets of simulated users?

Runs the study's paired benchmark (``strol-bench study``'s config) on ``--sets`` disjoint user
ranges of ``--users`` each (set k: first seed 20000 + k·users), then reads each set's first n
users for every n in ``--prefixes`` and prints, per n, each set's per-Task verdict and how far
the p-values that decide it sit from α. Choosing the default user count: the smallest n at which
every set gives every Task the same verdict, with margin to spare.

The work goes in rounds of one unit's users (4) per set, each round a resumable folder, so an
interrupted run leaves equally many users in every set; ``--lanes N --lane i`` splits the
rounds between N processes (one CPU each).

    python lab/study/study_seed_sets.py --users 40 --sets 5 --prefixes 20,28,32,40 \
        --out results/study-seed-sets

Or, running nothing here, read the sets from ``strol-bench study`` folders (set k: seeds
20000 + k·U on, the same users these rounds would run; set 0 is the study's own first U
users), one folder per set or one holding them all; a set no folder completes is left out:

    for k in 0 1 2 3 4; do
        strol-bench study --users 20 --seed $((20000 + 20 * k)) --out results/study-set$k
    done
    python lab/study/study_seed_sets.py --users 20 --sets 5 \
        --from-study results/study-set0 ... --from-study results/study-set4
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

from strol_gym.benchmarks.analysis.report import analyse
from strol_gym.benchmarks.analysis.stats import ALPHA
from strol_gym.benchmarks.engine.record import RunRecord
from strol_gym.benchmarks.engine.results import ResultsDir, ResultsError
from strol_gym.benchmarks.engine.runner import run_benchmark
from strol_gym.benchmarks.experiments.study import (
    BLOCK,
    H3_BASELINES,
    H3_METRICS,
    METRICS,
    SEED,
    TASKS,
    add_authors_regret,
    h3_verdicts,
    study_config,
)


def decisive_margin(a: Any, env: str, cond: str) -> tuple[float, float]:
    """(margin of the Task's verdict, smallest |p_Holm − α| of its four tests).

    "Supported" needs all four tests significant with StROL lower: it flips when the largest
    p_Holm rises above α, so its margin is α − max p. "Not supported" flips only when every
    failing test passes: its margin is the largest p − α among the failing tests (1 when a
    failing test has StROL higher: more users would not make it pass)."""
    tests = [a.test(env, cond, b, m) for m in H3_METRICS for b in H3_BASELINES]
    if any(t is None for t in tests):
        return math.nan, math.nan
    ps = [t["p_holm"] for t in tests]
    nearest = min(abs(p - ALPHA) for p in ps)
    failing = [t for t in tests if not (t["significant"] and t["mean_diff"] < 0)]
    if not failing:
        return ALPHA - max(ps), nearest
    return max(1.0 if t["mean_diff"] > 0 else t["p_holm"] - ALPHA for t in failing), nearest


def set_records(set_folder: Path) -> list[RunRecord]:
    """Every finished record of one set (its round folders)."""
    out: list[RunRecord] = []
    for folder in sorted(set_folder.glob("users-*")):
        if (folder / "meta.json").exists():
            out += ResultsDir.load(folder).read_records()
    return out


def analyse_prefix(
    records: list[RunRecord], first: int, n: int, version: str = "v0"
) -> list[dict[str, Any]]:
    """Verdicts and margins of one set's users ``first`` .. ``first + n − 1``."""
    config = study_config(TASKS, n, first, version=version)
    records = [r for r in records if first <= r["seed"] < first + n]
    a = analyse(config, records, [m for m in METRICS if all(m in r for r in records)])
    out = []
    for v, exp in zip(h3_verdicts(a), config.experiments, strict=True):
        margin, nearest = decisive_margin(a, exp.env, exp.condition.name)
        out.append({"task": v["task"], "verdict": v["verdict"], "margin": margin, "near": nearest})
    return out


def complete_users(records: list[RunRecord], first: int) -> int:
    """How many users from ``first`` on have every Task's and learner's run."""
    have: dict[int, int] = {}
    for r in records:
        have[r["seed"]] = have.get(r["seed"], 0) + 1
    full = len(TASKS) * len(study_config().learners)
    n = 0
    while have.get(first + n) == full:
        n += 1
    return n


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--users", type=int, default=40, help="users per set (40)")
    p.add_argument("--sets", type=int, default=5, help="disjoint seed sets (5)")
    p.add_argument("--prefixes", default="", help="user counts to analyse, e.g. 20,32 (--users)")
    p.add_argument("--out", default="results/study-seed-sets", help="parent of the set folders")
    p.add_argument("--lanes", type=int, default=1, help="processes sharing the rounds (1)")
    p.add_argument("--lane", type=int, default=0, help="this process's lane, 0..lanes-1 (0)")
    p.add_argument("--analyse-only", action="store_true", help="read the folders, run nothing")
    p.add_argument(
        "--run-sets",
        default="",
        help="run only these sets, e.g. 1,2,3,4 (set 0 = the study's own seeds, which a "
        "`strol-bench study` folder linked as OUT/set0/users-all can stand for); all analysed",
    )
    p.add_argument(
        "--env-version",
        choices=("v0", "v1", "v2"),
        default="v2",
        help="v2 (the study's default: the fitted population), v1 (its hand-set participant) "
        "or v0 (the published results)",
    )
    p.add_argument(
        "--from-study",
        action="append",
        default=None,
        metavar="FOLDER",
        help="read the sets from `strol-bench study` folders instead of running them "
        "(repeatable: e.g. one per set, --seed 20000 + k x users; a set every folder leaves "
        "incomplete is left out and said so)",
    )
    args = p.parse_args(argv)
    if args.users < 1 or args.sets < 1:
        p.error(f"--users and --sets must be >= 1, got {args.users} and {args.sets}")
    if not 0 <= args.lane < args.lanes:
        p.error(f"--lane must lie in 0..--lanes-1 ({args.lanes - 1}), got {args.lane}")
    prefixes = [int(x) for x in args.prefixes.split(",") if x.strip()] or [args.users]
    if any(not 2 <= n <= args.users for n in prefixes):
        p.error(f"--prefixes must lie in 2..--users ({args.users}), got {args.prefixes!r}")
    out = Path(args.out)
    firsts = [SEED + k * args.users for k in range(args.sets)]
    run_sets = [int(x) for x in args.run_sets.split(",") if x.strip()] or range(args.sets)
    if any(not 0 <= k < args.sets for k in run_sets):
        p.error(f"--run-sets must lie in 0..--sets-1 ({args.sets - 1}), got {args.run_sets!r}")
    rounds = [(j, k) for j in range(0, args.users, BLOCK) for k in run_sets]
    if args.from_study is not None:
        shared = []
        for folder in args.from_study:
            try:
                study = ResultsDir.load(Path(folder))
            except (OSError, ValueError, ResultsError) as e:
                p.error(f"--from-study: {e}")
            exps = study.config.experiments
            version = {e.env.split("-")[1] if "-" in e.env else "v0" for e in exps}
            if version != {args.env_version}:
                p.error(
                    f"--from-study {folder} holds StROL-Study-{sorted(version)}, not "
                    f"{args.env_version}"
                )
            shared += study.read_records()
        add_authors_regret(shared)  # once (it plans every run's θ̂ and θ*)
        records = [shared] * args.sets
    elif not args.analyse_only:
        for i, (j, k) in enumerate(rounds):
            if i % args.lanes != args.lane:
                continue
            n = min(BLOCK, args.users - j)
            folder = out / f"set{k}" / f"users-{j:03d}"
            t0, c0 = time.perf_counter(), time.process_time()
            config = study_config(TASKS, n, firsts[k] + j, version=args.env_version)
            run_benchmark(config, folder, jobs=1, quiet=True)
            print(
                f"set {k} users {j}..{j + n - 1}: wall {time.perf_counter() - t0:.1f} s, "
                f"CPU {time.process_time() - c0:.1f} s, load {os.getloadavg()[0]:.1f}",
                flush=True,
            )
    if args.from_study is None:
        records = [set_records(out / f"set{k}") for k in range(args.sets)]
        for r in records:
            add_authors_regret(r)  # once per set (it plans every run's θ̂ and θ*)
    counts = [complete_users(r, f) for r, f in zip(records, firsts, strict=True)]
    if args.from_study is not None:  # the sets the folders hold
        kept = [k for k, c in enumerate(counts) if c >= args.users]
        print(f"sets with all {args.users} users: {len(kept)} of {args.sets} ({kept})")
        records, firsts = [records[k] for k in kept], [firsts[k] for k in kept]
        counts = [counts[k] for k in kept]
    have = min(counts, default=0)
    print(f"complete users in every set: {have}")
    for n in sorted({n for n in prefixes if n <= have} | ({have} if have >= 2 else set())):
        print(f"\n{n} users per set:")
        rows = [
            analyse_prefix(r, f, n, args.env_version) for r, f in zip(records, firsts, strict=True)
        ]
        for t_index, task in enumerate(TASKS):
            cells = [r[t_index] for r in rows]
            words = ["S" if c["verdict"] == "H3 supported" else "-" for c in cells]
            agree = "agree" if len(set(words)) == 1 else "DIFFER"
            margins = ", ".join(f"{c['margin']:.3g}" for c in cells)
            near = min(c["near"] for c in cells)
            print(
                f"  Task {task}: {' '.join(words)} ({agree}); verdict margins {margins}; "
                f"nearest p_Holm to α: {near:.3g}"
            )
        worst = min(c["margin"] for r in rows for c in r)
        print(f"  smallest verdict margin: {worst:.3g} (S = H3 supported, - = not supported)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
