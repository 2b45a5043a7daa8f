"""Calibrating a study participant on seeds outside the study's (900 on; the study's are
20000-29999): per Task and learner, its corrections, correction time (ours and the authors'
way, per episode and per correction), give-up rate and regret, with the training human's
noise (σ = 0.25). ``--env-version v2`` (default): StROL-Study-v2 with its fitted population
(the acceptance threshold is calibrated so corrections per session come near the real people's
3.2 / 5.4 / 5.6); ``v1``: v1 with its hand-set participant.

    python lab/study/study_calibration.py --users 4 --out results/study-calibration

The paper's study: correction time (authors' way) 1.4–2.5 s per participant and Task; "some"
participants gave up. The runs go through the study's runner (a resumable results folder)."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from strol_gym.benchmarks.engine.record import RunRecord
from strol_gym.benchmarks.engine.runner import run_benchmark
from strol_gym.benchmarks.experiments.study import TASKS, study_config

SEED = 900
LEARNERS = ("one", "mof", "strol")


def rows(records: list[RunRecord]) -> list[str]:
    """One markdown row per Task × learner."""
    out = []
    for env in dict.fromkeys(r["env"] for r in records):
        for learner in LEARNERS:
            rs = [r for r in records if r["env"] == env and r["learner"] == learner]
            if not rs:
                continue
            n = np.array([r["corrections"] for r in rs], dtype=float)
            ours = np.array([r["correction_time"] for r in rs], dtype=float)
            auth = np.array([r["correction_time_authors"] for r in rs], dtype=float)
            gave = np.array([r.get("gave_up", np.nan) for r in rs], dtype=float)
            reg = np.array([r["regret"] for r in rs], dtype=float)
            per = ours.sum() / max(n.sum(), 1.0)
            per_a = auth.sum() / max(n.sum(), 1.0)
            out.append(
                f"| {env[5]} | {learner} | {len(rs)} | {n.mean():.1f} | {ours.mean():.1f} "
                f"| {per:.2f} | {auth.mean():.2f} | {per_a:.2f} | {np.nanmean(gave):.0%} "
                f"| {reg.mean():.2f} ({np.median(reg):.2f}) |"
            )
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--users", type=int, default=4, help="seeds per Task (4)")
    p.add_argument("--seed", type=int, default=SEED, help=f"first seed ({SEED})")
    p.add_argument(
        "--env-version",
        choices=("v1", "v2"),
        default="v2",
        help="v2 (the fitted population) or v1 (its hand-set participant); default v2",
    )
    p.add_argument(
        "--participant",
        choices=("fitted", "observer", "oracle"),
        default=None,
        help="the simulated person (default: the version's own; fitted exists on v2 only)",
    )
    p.add_argument("--out", default="results/study-calibration", help="results folder")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (1)")
    args = p.parse_args(argv)
    if args.users < 1 or not 0 <= args.seed < 20_000 - args.users:
        p.error(f"--users must be >= 1 and the seeds below the study's 20000, got {args}")
    try:
        config = study_config(
            TASKS, args.users, args.seed, LEARNERS, args.env_version, args.participant
        )
    except ValueError as e:
        p.error(str(e))
    t0, c0 = time.perf_counter(), time.process_time()
    rd = run_benchmark(config, Path(args.out), jobs=args.jobs, quiet=True)
    print(
        f"wall {time.perf_counter() - t0:.1f} s, CPU {time.process_time() - c0:.1f} s "
        f"(this process), load {os.getloadavg()[0]:.1f}"
    )
    head = (
        "| Task | learner | n | corrections | correction time (s) | per correction (s) "
        "| authors' way (s) | authors' per correction (s) | gave up | regret mean (median) |"
    )
    print("\n".join([head, "|" + "---|" * 10, *rows(rd.read_records())]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
