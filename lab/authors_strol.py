"""Measurements behind the paper's-StROL pages: λ on the authors' ĝ, and features like for like.

    python lab/authors_strol.py DATA GDIR
    python lab/authors_strol.py --table REPLAY_REF_STROL REPLAY_REF_PAPER

DATA is a ``user_study/data`` tree, GDIR a checkout's ``user_study/g_data`` (read at run time,
nothing written). Prints

1. per λ on the authors' ĝ, the StROL sessions whose implied θ̂0 = θ̂_final − Σ(g + λ ĝ) lies in
   [−1, 1]^d (Task 1; Tasks 2-3);
2. per Task, Gradient and One replayed on every session's logged pairs (x_k, 3Δx_k) from its
   implied θ̂0 (the session's own rule) with four settings: (S) this suite's Task as shipped
   (α = 2) at the cup's pose, (A) the same at α = 1 (theirs), (B) this suite's φ (α = 1) with
   the hand's position and the cup's orientation (only the point φ's distances are taken at
   moves), (C) the authors' φ at the hand's pose (α = 1); mean 1 − cos and error to θ*, and
   Wilcoxon p of S vs A (α), A vs B (the point) and B vs C (the orientation feature, the
   authors' unclipped x + u and −|z|). StROL sessions' θ̂0 needs GDIR.
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.stats import wilcoxon

from strol_gym.benchmarks.sessions.authors_frame import fit_transform
from strol_gym.benchmarks.sessions.authors_ghat import load_authors_ghat
from strol_gym.benchmarks.sessions.authors_rules import (
    RULES,
    authors_task,
    reconstruct,
    sample_updates,
)
from strol_gym.benchmarks.sessions.import_study import read_sessions, state_step
from strol_gym.learners.registry import make_learner
from strol_gym.metrics import cos_error, error
from strol_gym.tasks.study import STUDY_TASKS

LAMBDAS = (0.0, 0.2, 0.25, 0.3, 0.5, 1.0)


def lambda_sweep(sessions, gdir: str) -> None:
    """Implied-θ̂0-in-box counts for StROL sessions per λ (Task 1; Tasks 2-3)."""
    sums = []
    for s in sessions:
        if s.alg != "ours" or s.theta_final is None:
            continue
        task, g = authors_task(s.task), load_authors_ghat(gdir, s.task)
        sg, sh = np.zeros(task.dim), np.zeros(task.dim)
        for poses in s.corrections:
            if len(poses) >= 2:
                x, u = sample_updates(poses, s.task)
                sg += task.g(x, u, np.zeros_like(u)).sum(axis=0)
                sh += g(x, u).sum(axis=0)
        sums.append((s.task, s.theta_final, sg, sh))
    print("| λ on ĝ | Task 1 | Tasks 2-3 |\n|---|---|---|")
    for lam in LAMBDAS:
        cells = []
        for tasks in ((1,), (2, 3)):
            mine = [(f, sg, sh) for t, f, sg, sh in sums if t in tasks]
            inside = sum(bool(np.all(np.abs(f - sg - lam * sh) <= 1.0)) for f, sg, sh in mine)
            cells.append(f"{inside} / {len(mine)}")
        print(f"| {lam:g} | " + " | ".join(cells) + " |")


def pairs(kind: str, poses: np.ndarray, number: int, fit) -> tuple[np.ndarray, np.ndarray]:
    """(x_k, 3Δx_k) of one correction's logged poses in feature map ``kind`` (A, B or C)."""
    if kind == "C":
        return sample_updates(poses, number)
    cup = fit.to_cup(poses)  # S, A
    if kind == "B":
        cup = np.concatenate([poses[:, :3], cup[:, 3:]], axis=1)
    task = STUDY_TASKS[number]()
    states = cup if task.oriented else cup[:, :3]
    return states[:-1], 3.0 * state_step(task, states[:-1], states[1:])


def features_like_for_like(sessions, gdir: str) -> None:
    fit = fit_transform()
    kinds = "SABC"
    print(
        "\n| Task | rule | sessions | 1 − cos S | A | B | C | p S vs A | p A vs B | p B vs C "
        "| error S | A | B | C |"
    )
    print("|---" * 15 + "|")
    for number in (1, 2, 3):
        mine = [s for s in sessions if s.task == number and s.theta_final is not None]
        for rule in ("gradient", "one"):
            cos: dict[str, list[float]] = {k: [] for k in kinds}
            err: dict[str, list[float]] = {k: [] for k in kinds}
            for s in mine:
                th0, _ = reconstruct(s.theta_final, s.corrections, number, RULES[s.alg], gdir)
                for kind in kinds:
                    task = (
                        authors_task(number)
                        if kind == "C"
                        else STUDY_TASKS[number](alpha=2.0 if kind == "S" else 1.0)
                    )
                    learner = make_learner(rule, task=task)
                    learner.reset(th0)
                    for poses in s.corrections:
                        if len(poses) >= 2:
                            x, u = pairs(kind, poses, number, fit)
                            for xk, uk in zip(x, u, strict=True):
                                learner.update(xk, uk, np.zeros_like(uk))
                    cos[kind].append(cos_error(s.theta_star, learner.theta))
                    err[kind].append(error(s.theta_star, learner.theta))
            c = {k: np.array(v) for k, v in cos.items()}
            e = {k: np.array(v) for k, v in err.items()}
            ps = [
                wilcoxon(c[a], c[b]).pvalue if np.any(c[a] != c[b]) else 1.0
                for a, b in ("SA", "AB", "BC")
            ]
            cells = [f"{c[k].mean():.3f}" for k in kinds] + [f"{p:.2g}" for p in ps]
            cells += [f"{e[k].mean():.3f}" for k in kinds]
            print(f"| {number} | {rule} | {len(mine)} | " + " | ".join(cells) + " |")


LABELS = {
    "gradient": ("Gradient", "ours"),
    "one": ("One", "ours"),
    "mof": ("MOF", "ours"),
    "strol": ("**StROL, this suite's** (our ĝ)", "ours"),
    "strol-paper": ("**StROL, the paper's** (their ĝ, λ 0.25)", "authors'"),
    "gradient@authors": ("Gradient", "authors'"),
    "one@authors": ("One", "authors'"),
}


def both_strols_table(ref_strol: str, ref_paper: str) -> None:
    """Per Task: each learner's mean ± sd of 1 − cos, error and regret over sessions, and the
    Wilcoxon Holm p of 1 − cos against each StROL (two ``strol-bench replay`` folders of the same
    logs and learners, ``--reference strol`` and ``--reference strol-paper``)."""
    import csv
    from pathlib import Path

    with open(Path(ref_strol) / "replay_sessions.csv", encoding="utf-8") as f:
        per = list(csv.DictReader(f))
    p: dict[tuple[str, str, str], float] = {}
    for folder in (ref_strol, ref_paper):
        with open(Path(folder) / "replay_stats.csv", encoding="utf-8") as f:
            for r in csv.DictReader(f):
                if r["test"] == "paired t" and r["metric"] == "cos_error":
                    p[(r["task"], r["learner"], r["baseline"])] = float(r["wilcoxon_p_holm"])

    def cell(task: str, name: str, metric: str) -> str:
        v = np.array([float(r[metric]) for r in per if r["task"] == task and r["learner"] == name])
        return "n/a" if np.isnan(v).all() else f"{v.mean():.2f} ± {v.std(ddof=1):.2f}"

    def pcell(task: str, ref: str, name: str) -> str:
        if name == ref:
            return "ref."
        v = p.get((task, ref, name))
        return "" if v is None else ("< 0.001" if v < 0.001 else f"{v:.3f}")

    print(
        "| Task | learner | feature space | 1 − cos(θ*, θ̂) | p vs this suite's StROL | "
        "p vs the paper's StROL | error ‖θ* − θ̂‖ | regret |"
    )
    print("|---" * 8 + "|")
    for task in sorted({r["task"] for r in per}):
        for name, (label, space) in LABELS.items():
            print(
                f"| {task[-1]} | {label} | {space} | {cell(task, name, 'cos_error')} | "
                f"{pcell(task, 'strol', name)} | {pcell(task, 'strol-paper', name)} | "
                f"{cell(task, name, 'error')} | {cell(task, name, 'regret')} |"
            )


def main(argv: list[str]) -> int:
    if argv and argv[0] == "--table":
        both_strols_table(*argv[1:])
        return 0
    data, gdir = argv
    sessions = read_sessions(data)
    lambda_sweep(sessions, gdir)
    features_like_for_like(sessions, gdir)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
