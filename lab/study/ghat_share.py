"""How much of StROL's step is its ĝ: v2's StROL against the paper's, on the people's own pushes.

For every correction of the twelve people (imported one line per correction: x, the whole
displacement u_H in the Study Tasks' frame, and the poses the authors' loop logged), both
StROLs' steps split into their g and λ·ĝ parts:

- v2's StROL (this suite's ĝ for StROL-Study-v2, v2's φ): one step per push, α·g(x, u_H) and
  α·λ·ĝ(x, u_H);
- the paper's StROL (the authors' ĝ read from GDIR, their φ, α = 1): one step per consecutive
  pair of logged poses, Σ g(x_k, 3Δ_k) and Σ λ·ĝ(x_k, 3Δ_k).

Printed per Task: corrections, the median norm of each part, and the median of ‖λĝ‖ / ‖g‖.

    python -m lab.study.ghat_share LOGS GDIR

LOGS: ``strol-bench import-study DATA --out LOGS --theta0 implied --authors-ghat GDIR``.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from strol_gym.benchmarks.sessions.authors_rules import PAPER, rule_learner, sample_updates
from strol_gym.benchmarks.sessions.replay_folder import find_logs
from strol_gym.benchmarks.sessions.study_card import _records
from strol_gym.learners.registry import make_learner
from strol_gym.tasks.study import STUDY_TASKS_V2


def parts(learner: object, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(α·Σ g, α·Σ (G − g)) of ``learner``'s steps at the rows of ``x``, ``u`` (θ̂ not used:
    neither StROL's direction depends on it)."""
    task = learner.task  # type: ignore[attr-defined]
    zero = np.zeros_like(u)
    theta = np.repeat(np.asarray(learner.theta)[None], len(x), 0)  # type: ignore[attr-defined]
    g = task.g(x, u, zero)
    full = learner.direction(x, u, zero, theta)  # type: ignore[attr-defined]
    return task.alpha * g.sum(0), task.alpha * (full - g).sum(0)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs")
    ap.add_argument("ghat", help="the authors' user_study/g_data")
    args = ap.parse_args(argv)
    logs = [_records(p) for p in find_logs(args.logs)]
    print("Task | corrections | v2: ‖α g‖, ‖α λ ĝ‖, ratio | paper: ‖Σ g‖, ‖Σ λ ĝ‖, ratio")
    for number in (1, 2, 3):
        ours = make_learner("strol", task=STUDY_TASKS_V2[number]())
        paper = rule_learner(PAPER, number, args.ghat)
        rows = []
        for recs in logs:
            if recs[0]["extra"]["study_task"] != number:
                continue
            for c in recs:
                poses = c.get("authors_poses")
                if poses is None or len(poses) < 2:
                    continue
                x = np.asarray(c["x"], dtype=np.float64)[None]
                u = np.asarray(c["u_h"], dtype=np.float64)[None]
                g1, h1 = parts(ours, x, u)
                g2, h2 = parts(paper, *sample_updates(np.asarray(poses), number))
                rows.append([np.linalg.norm(v) for v in (g1, h1, g2, h2)])
        r = np.array(rows)
        med = np.median(r, axis=0)
        ratio_ours = np.median(r[:, 1] / np.maximum(r[:, 0], 1e-12))
        ratio_paper = np.median(r[:, 3] / np.maximum(r[:, 2], 1e-12))
        print(
            f"{number} | {len(r)} | {med[0]:.3f}, {med[1]:.3f}, {ratio_ours:.2f} | "
            f"{med[2]:.3f}, {med[3]:.3f}, {ratio_paper:.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
