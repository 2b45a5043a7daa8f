"""The paper's StROL in StROL-Study-v2's loop: a ``--plugin`` for ``strol-bench study``.

``strol-paper-v2`` is the StROL the study ran (``strol-paper``: the authors' φ, their trained ĝ
read at run time from a local checkout, λ = 0.25, α = 1), fed each of v2's pushes as the authors'
loop fed a push: the cup's straight path from x to x + u_H in poses 1.26 cm apart (the people's
median step between logged poses), mapped into the authors' hand frame
(``authors_frame.fit_transform``), one update per consecutive pair with u = 3 Δ
(``authors_rules.sample_updates``). The simulated people and everything else are v2's; only the
learner changes. It answers whether v2's simulated H3 turns on the people or on the ĝ.

    export STROL_AUTHORS_GHAT=/path/to/StROL_RAL/user_study/g_data
    strol-bench study --users 20 --learners one,mof,strol-paper-v2 \\
        --reference strol-paper-v2 --plugin lab/study/paper_strol.py --out OUT

The authors' ĝ is never copied: each worker reads it from ``STROL_AUTHORS_GHAT``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from strol_gym.benchmarks.engine.record import RunRecord
from strol_gym.benchmarks.sessions.authors_frame import fit_transform
from strol_gym.benchmarks.sessions.authors_ghat import FLAG
from strol_gym.benchmarks.sessions.authors_rules import PAPER, rule_learner, sample_updates
from strol_gym.learners.protocol import LinearRuleLearner
from strol_gym.learners.registry import LEARNERS, register_learner
from strol_gym.tasks.base import Task

NAME = "strol-paper-v2"
ENV = "STROL_AUTHORS_GHAT"
POSE_STEP = 0.0126
"""m between consecutive poses the authors' loop logged during a correction: the median over
the twelve people's corrections (``authors_poses`` of ``strol-bench import-study``'s logs)."""


def ghat_dir() -> str:
    """The authors' ``user_study/g_data`` from ``STROL_AUTHORS_GHAT`` (ValueError naming it)."""
    gdir = os.environ.get(ENV)
    if not gdir:
        raise ValueError(
            f"learner {NAME!r} needs the authors' ĝ: set {ENV} to a local checkout's "
            f"user_study/g_data (what {FLAG} takes elsewhere)"
        )
    return gdir


class PaperStrolV2(LinearRuleLearner):
    """The paper's StROL stepping once per pair of poses along each v2 push (module docstring)."""

    name = NAME

    def __init__(self, task: Task, **kwargs: Any) -> None:
        super().__init__(task)
        self.number = int(getattr(task, "number", 0))
        self.inner = rule_learner(PAPER, self.number, ghat_dir())
        self.frame = fit_transform()

    def update(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None = None) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        u = np.asarray(u_h, dtype=np.float64)
        n = max(1, round(float(np.linalg.norm(u[:3])) / POSE_STEP))
        cup = x[None] + u[None] * (np.arange(n + 1) / n)[:, None]
        if cup.shape[1] == 3:  # Task 1's state holds the cup's position; upright otherwise
            cup = np.concatenate([cup, np.zeros_like(cup)], axis=1)
        xs, us = sample_updates(self.frame.to_logged(cup), self.number)
        self.inner.theta = np.asarray(self.theta, dtype=np.float64).copy()
        for xk, uk in zip(xs, us, strict=True):
            self.inner.update(xk, uk, np.zeros_like(uk))
        self.theta = np.asarray(self.inner.theta, dtype=np.float64).copy()
        return self.theta.copy()

    def config(self) -> dict[str, Any]:
        return {**self.inner.config(), "pose_step": POSE_STEP}


if NAME not in LEARNERS:
    register_learner(NAME, PaperStrolV2, display="StROL (paper's ĝ)")


def count_ratio(
    records: Sequence[RunRecord], learner: str, base: str = "one", reps: int = 2000
) -> tuple[float, float, float]:
    """Corrections per session under ``learner`` over those under ``base`` (the same users and
    Tasks), with a 95 % interval over users resampled (seed 0)."""
    seeds = sorted({r["seed"] for r in records})
    per = {(r["seed"], r["learner"]): 0.0 for r in records}
    for r in records:
        per[r["seed"], r["learner"]] += float(r["corrections"])
    a = np.array([per[s, learner] for s in seeds])
    b = np.array([per[s, base] for s in seeds])
    pick = np.random.default_rng(0).integers(0, len(seeds), (reps, len(seeds)))
    boot = a[pick].sum(axis=1) / b[pick].sum(axis=1)
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return float(a.sum() / b.sum()), float(lo), float(hi)


def main(argv: list[str] | None = None) -> int:
    """Each study folder's H3 lines, then all of them pooled: the paper's pooled tests over One,
    MOF and the reference learner, and its corrections per session against One's."""
    import argparse
    import json

    from strol_gym.benchmarks.analysis.report import pooled_tests
    from strol_gym.benchmarks.engine.results import ResultsDir
    from strol_gym.benchmarks.experiments.study import add_authors_regret

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("folders", nargs="+", help="strol-bench study results folders")
    ap.add_argument("--learner", default=NAME, help=f"the learner tested (default {NAME})")
    args = ap.parse_args(argv)
    learners = ("one", "mof", args.learner)
    pooled: list[RunRecord] = []
    for folder in args.folders:
        recs = ResultsDir.load(folder).read_records()
        pooled += recs
        study = json.load(open(f"{folder}/study.json"))
        verdicts = "; ".join(f"Task {v['task']}: {v['verdict']}" for v in study["verdicts"])
        ratio = count_ratio(recs, args.learner)
        print(
            f"{folder}: {verdicts}; corrections / One's {ratio[0]:.2f} [{ratio[1]:.2f}, "
            f"{ratio[2]:.2f}]"
        )
    add_authors_regret(pooled)
    envs = sorted({r["env"] for r in pooled})
    print(f"pooled: {len({r['seed'] for r in pooled})} users")
    for m in ("regret", "regret_authors", "correction_time_authors", "corrections"):
        p = pooled_tests(pooled, envs, learners, m)
        a = p["anova"]
        means = " / ".join(f"{p['means'][k]:.3f}" for k in learners)
        pairs = ", ".join(
            f"{x['a']}-{x['b']} {x['mean_diff']:+.3f} (p_Holm {x['p_holm']:.2g})"
            for x in p["pairs"]
        )
        print(
            f"  {m}: {means}; F({a.df1_gg:.2f}, {a.df2_gg:.1f}) = {a.F:.2f}, "
            f"p_GG = {a.p_gg:.2g}; {pairs}"
        )
    for t in sorted({r["env"] for r in pooled}):
        sub = [r for r in pooled if r["env"] == t]
        ratio = count_ratio(sub, args.learner)
        print(f"  {t}: corrections / One's {ratio[0]:.2f} [{ratio[1]:.2f}, {ratio[2]:.2f}]")
    ratio = count_ratio(pooled, args.learner)
    print(f"  all Tasks: corrections / One's {ratio[0]:.2f} [{ratio[1]:.2f}, {ratio[2]:.2f}]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
