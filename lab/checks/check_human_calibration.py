"""How often does ``strol-bench check-human`` fail a person that is right?

A person is checked against replicates of itself: of N replicates, each in turn is judged as if
it were the real people against a band from the S replicates that follow it (cyclically, so
the reference differs from one judged replicate to the next and never holds it). The share
failing at least one check is the band's family-wise error (its target: 1 − level = 5 %), with
its Wilson 95 % interval (the N judgements share references, so the interval is a guide); per
check, the share failing it. Two rules: ``judge`` (the check's: the judged value ranked as one
more replicate, γ set on all S + 1) and ``old`` (γ set on the S replicates, each counting
itself, the judged value's p among them without itself: the rule before, which fails about
twice as often when γ is a few multiples of 2/S).

    python -m lab.checks.check_human_calibration LOGS --population --draws 4000 --save V.npz
    python -m lab.checks.check_human_calibration --values V.npz --reference 1079,2000

LOGS: ``strol-bench import-study DATA --out LOGS --theta0 implied --authors-ghat GDIR``.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.check_human import (
    LEVEL,
    AtLoggedMoments,
    StudyPopulation,
    judge,
    read_sessions,
    run_check,
    two_sided_p,
)


def old_rule(ref: np.ndarray, value: np.ndarray, level: float = LEVEL) -> np.ndarray:
    """The rule before: γ the lower (1 − level) quantile over ``ref``'s rows of their smallest
    p (each row counted among the rows), ``value``'s p among ``ref`` without itself; whether
    each check fails."""
    p = np.column_stack([two_sided_p(ref[:, k], ref[:, k]) for k in range(ref.shape[1])])
    worst = np.nanmin(np.where(np.isnan(p), np.inf, p), axis=1)
    gamma = float(np.quantile(worst, 1.0 - level, method="lower"))
    pv = np.array([two_sided_p(ref[:, k], value[k])[0] for k in range(ref.shape[1])])
    return ~(np.isfinite(pv) & (pv >= gamma))


def new_rule(ref: np.ndarray, value: np.ndarray, level: float = LEVEL) -> np.ndarray:
    """check-human's rule (:func:`judge`): whether each check fails."""
    gamma, _, p = judge(ref, value, level)
    return ~(np.isfinite(p) & (p >= gamma))


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
    """Each row of ``values`` (N, J) judged against the ``reference`` rows after it (cyclic),
    by both rules."""
    n = len(values)
    if not 0 < reference < n:
        raise ValueError(f"--reference must be in [1, {n - 1}] for {n} replicates")
    out: dict[str, Any] = {"reference": reference, "judged": n}
    for name, rule in (("judge", new_rule), ("old", old_rule)):
        fails = np.zeros(values.shape, dtype=bool)
        for i in range(n):
            ref = values[(i + 1 + np.arange(reference)) % n]
            fails[i] = rule(ref, values[i])
        k = int(fails.any(axis=1).sum())
        out[name] = {"any": k / n, "wilson": wilson(k, n), "per_check": fails.mean(axis=0)}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs", nargs="?")
    who = ap.add_mutually_exclusive_group()
    who.add_argument("--population", action="store_true")
    who.add_argument("--human")
    ap.add_argument("--draws", type=int, default=4000, help="replicates simulated (N)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--save", help="write the replicates' values here (.npz)")
    ap.add_argument("--values", help="read them from here instead of simulating")
    ap.add_argument("--reference", default="1079,2000", help="comma-separated S")
    args = ap.parse_args(argv)
    if args.values:
        saved = np.load(args.values)
        matrix, cols = saved["values"], [str(c) for c in saved["cols"]]
    else:
        if not args.logs or not (args.population or args.human):
            ap.error("LOGS and --population or --human, or --values")
        real = read_sessions(args.logs)
        person = StudyPopulation() if args.population else AtLoggedMoments(args.human)
        values: dict[tuple[int, str], np.ndarray] = {}
        run_check(real, person, args.draws, args.seed, values_out=values)
        cols = [f"T{t} {k}" for t, k in values]
        matrix = np.column_stack(list(values.values()))
        if args.save:
            np.savez(args.save, values=matrix, cols=np.array(cols))
    print(f"{len(matrix)} replicates, {matrix.shape[1]} checks")
    for s in (int(v) for v in args.reference.split(",")):
        res = calibrate(matrix, s)
        print(f"reference S = {s}, each of {res['judged']} replicates judged against S others")
        for name in ("judge", "old"):
            r = res[name]
            lo, hi = r["wilson"]
            worst = sorted(zip(r["per_check"], cols, strict=True), reverse=True)[:4]
            tops = ", ".join(f"{c} {v:.3f}" for v, c in worst)
            print(f"  {name:6s} any check failed {r['any']:.4f} [{lo:.4f}, {hi:.4f}]; {tops}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
