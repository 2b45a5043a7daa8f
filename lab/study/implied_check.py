"""The implied-θ̂0 check: does the rule a session ran explain its final θ̂ from a θ̂0 in [−1, 1]^d?

    python -m lab.study.implied_check DIR

DIR is a ``user_study/data`` tree (read with the plain-pickle reader). The authors drew θ̂0
uniformly from [−1, 1]^d and logged only the final θ̂; their updates never depend on θ̂, so
θ̂0 = θ̂_final − Σ updates (:mod:`authors_rules`: our One and Gradient rules under their settings).
Per folder (b1 = One, b2 = MOF, ours = StROL) and rule, the count of sessions whose implied θ̂0
lies inside the box. StROL sessions are checked here with the gradient rule alone, a control
the check is expected to reject; ``strol-bench import-study --theta0 implied --authors-ghat
GDIR`` checks them under their own rule (with the authors' ĝ).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from strol_gym.benchmarks.sessions.authors_rules import implied_theta0
from strol_gym.benchmarks.sessions.import_study import read_sessions

CHECKS = (
    ("b1", "one"),
    ("b2", "gradient"),
    ("b2", "one"),
    ("b1", "gradient"),
    ("ours", "gradient"),
)
"""(folder, rule) pairs: each folder's own rule, the other rule as a control, StROL without ĝ."""


def implied_counts(root: str) -> list[tuple[str, str, int, int]]:
    """(folder, rule, inside, sessions with a final θ̂) for each of ``CHECKS``."""
    sessions = read_sessions(root)
    out = []
    for alg, rule in CHECKS:
        inside = total = 0
        for s in sessions:
            if s.alg != alg or s.theta_final is None:
                continue
            th0 = implied_theta0(s.theta_final, s.corrections, s.task, rule)
            inside += int(np.all(np.abs(th0) <= 1.0))
            total += 1
        out.append((alg, rule, inside, total))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("dir", help="a user_study/data tree")
    args = p.parse_args(argv)
    for alg, rule, inside, total in implied_counts(args.dir):
        print(
            f"{alg:5s} sessions under our {rule:8s} rule: "
            f"implied θ̂0 in [−1, 1]^d in {inside}/{total}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
