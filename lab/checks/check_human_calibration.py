"""How often does ``strol-bench check-human`` fail a person that is right?

A person is checked against replicates of itself: ``--reference`` replicates set the joint band
(``check_human.joint_band``) as the check does, and each of ``--fresh`` further replicates of the
same person is checked against it as if it were the real people. The share of fresh replicates
failing at least one check is the band's family-wise error (its target: 1 − LEVEL = 5 %), with
its Wilson 95 % interval; per check, the share failing it. Two ways of ranking the checked value
among the reference: as ``two_sided_p`` does (the value's share among the
replicates), and counting the value itself as a replicate's p-value counts it (2·min(#≤ + 1,
#≥ + 1)/(S + 1)).

    python -m lab.checks.check_human_calibration LOGS --population --reference 1000 --fresh 1000

LOGS: ``strol-bench import-study DATA --out LOGS --theta0 implied --authors-ghat GDIR``.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.check_human import (
    AtLoggedMoments,
    StudyPopulation,
    joint_band,
    read_sessions,
    run_check,
    two_sided_p,
)


def counted_p(draws: np.ndarray, value: np.ndarray) -> np.ndarray:
    """The two-sided rank p-value of each ``value`` among ``draws`` (S,), the value counted as
    one of S + 1: 2·min(#≤ + 1, #≥ + 1)/(S + 1), at most 1."""
    d = np.sort(draws[np.isfinite(draws)])
    v = np.asarray(value, dtype=np.float64)
    le = np.searchsorted(d, v, side="right") + 1
    ge = len(d) - np.searchsorted(d, v, side="left") + 1
    p = np.minimum(1.0, 2.0 * np.minimum(le, ge) / (len(d) + 1))
    return np.where(np.isfinite(v), p, np.nan)


def wilson(k: int, n: int) -> tuple[float, float]:
    """Wilson's 95 % interval of k / n."""
    z = 1.959963984540054
    if n == 0:
        return math.nan, math.nan
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return mid - half, mid + half


def calibrate(values: np.ndarray, reference: int) -> dict[str, Any]:
    """The band of the first ``reference`` rows of ``values`` (S + R, J) and how the other R
    rows fare against it, both ways of ranking them."""
    ref, fresh = values[:reference], values[reference:]
    gamma, _ = joint_band(ref)
    out: dict[str, Any] = {"gamma": gamma, "reference": reference, "fresh": len(fresh)}
    for name, rank in (("share", two_sided_p), ("counted", counted_p)):
        p = np.column_stack([rank(ref[:, j], fresh[:, j]) for j in range(values.shape[1])])
        fail = np.isfinite(p) & (p < gamma)
        k = int(fail.any(axis=1).sum())
        out[name] = {
            "any": k / len(fresh),
            "wilson": wilson(k, len(fresh)),
            "per_check": fail.mean(axis=0).tolist(),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs")
    who = ap.add_mutually_exclusive_group(required=True)
    who.add_argument("--population", action="store_true")
    who.add_argument("--human")
    ap.add_argument("--reference", type=int, default=1000)
    ap.add_argument("--fresh", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    real = read_sessions(args.logs)
    person = StudyPopulation() if args.population else AtLoggedMoments(args.human)
    values: dict[tuple[int, str], np.ndarray] = {}
    run_check(real, person, args.reference + args.fresh, args.seed, values_out=values)
    cols = list(values)
    matrix = np.column_stack([values[c] for c in cols])
    for s in sorted({200, 500, args.reference}):
        if s > args.reference:
            continue
        res = calibrate(np.concatenate([matrix[:s], matrix[args.reference :]]), s)
        print(f"reference {s}, fresh {res['fresh']}: gamma {res['gamma']:.4g}")
        for name in ("share", "counted"):
            r = res[name]
            lo, hi = r["wilson"]
            worst = sorted(zip(r["per_check"], cols, strict=True), reverse=True)[:4]
            tops = ", ".join(f"T{t} {k} {v:.3f}" for v, (t, k) in worst)
            print(f"  {name:8s} any check failed {r['any']:.3f} [{lo:.3f}, {hi:.3f}]; {tops}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
