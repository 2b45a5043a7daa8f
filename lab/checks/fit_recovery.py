"""Does ``fit-human`` get back what made the data? Parameter recovery and model selection.

For each model it simulates datasets with known, non-default parameters (people taught by the
one teaching loop, ``humans.teach``: θ* from the Task's prior, the Gradient learner from the
prior's mean, the Task's robot policy, 5 corrections each), fits the model back and reports,
per parameter, the coverage of the 95 % bootstrap interval and the bias against a quarter of
the mean interval width. Then model selection at matched spreads: data from one model, every
candidate fitted, the one with the highest held-out log-likelihood chosen: the confusion matrix.

    nice python -m lab.checks.fit_recovery --datasets 20 \
        --out results/fit-recovery

The CI test (tests/test_fit_human.py) runs the same functions on 5 datasets and fewer samples.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.fitting import (
    DEFAULT_INTERVAL,
    INTERVALS,
    Corrections,
    bca_intervals,
    bootstrap_draws,
    family,
    fit,
    jackknife_draws,
    maximise,
    prepare,
    sandwich_intervals,
    select,
    usable,
)
from strol_gym.files import write_text_atomic
from strol_gym.humans import human_model, teach
from strol_gym.learners.registry import make_learner
from strol_gym.tasks import make_task
from strol_gym.tasks.base import Task

RECOVERY: dict[str, dict[str, float]] = {
    "nominal": {"sigma": 0.35, "bias": 0.1},
    "boltzmann": {"sigma": 0.2, "bias": 0.0, "beta": 20.0},
    "myopic": {"sigma": 0.3, "bias": -0.1},
    "skipping": {"sigma": 0.25, "bias": 0.0, "p": 0.25},
    "over": {"sigma": 0.25, "bias": 0.0, "scale": 1.6},
    "under": {"sigma": 0.2, "bias": 0.0, "scale": 0.6},
    "mistaken": {"sigma": 0.2, "bias": 0.0, "rate": 0.3},
    "feature-noise": {"sigma": 0.15, "bias": 0.0, "kappa": 0.4},
    "competence": {"sigma": 0.25, "bias": 0.0, "p_good": 0.85, "p_bad": 0.4},
    "hazard": {"sigma": 0.25, "bias": 0.0, "rate": 1.5, "gamma": 2.0},
    "margin-noise": {"sigma": 0.2, "bias": 0.0, "kappa": 0.3, "equal": 0.15},
    "scale-free": {"sigma": 0.2, "bias": 0.0, "beta_rel": 8.0},
    "reversing": {"sigma": 0.2, "bias": 0.0, "rate": 0.2},
}
"""Known, non-default parameters each model's datasets are simulated with."""
FITTED_AS: dict[str, dict[str, Any]] = {
    "margin-noise": {
        "sigma0": lambda t: t["sigma"] + t["kappa"],
        "sigma_half": lambda t: t["sigma"] + 0.5 * t["kappa"],
    },
}
"""The truth of parameters a family fits or derives besides the model's own (``margin-noise``
fits the noise at margin 0, σ0 = σ + κ, and derives κ and the noise at margin ½)."""
SELECTION: dict[str, tuple[str, dict[str, float]]] = {
    "nominal σ 0.35": ("nominal", {"sigma": 0.35}),
    "boltzmann (matched)": ("boltzmann", {"sigma": 0.0}),  # β set by matched_beta
    "mistaken 0.1": ("mistaken", {"sigma": 0.35, "rate": 0.1}),
}
"""The selection scenarios: nominal σ 0.35 against Boltzmann with β giving the same mean
|u_H − u*| (σ 0), and mistaken at rate 0.1 (σ 0.35) against nominal."""
CANDIDATES = ("nominal", "boltzmann", "mistaken")


def simulate_people(
    task: Task,
    human: str,
    n_people: int,
    seed: int,
    n_corrections: int = 5,
    robot: bool = True,
    **params: Any,
) -> Corrections:
    """``n_people`` people of ``human`` (with ``params``) teaching the Gradient learner: every
    correction as a log would hold it (x, u_H, u_R, θ*, θ̂ before it). u_R is the Task's robot
    policy (``robot``; else 0: the tests' cheaper episodes)."""
    kw = {k: v for k, v in params.items() if k not in ("sigma", "bias", "beta")}
    model = human_model(
        human,
        task,
        sigma=params.get("sigma", 0.0),
        bias=params.get("bias", 0.0),
        beta=params.get("beta", 50.0),
        **kw,
    )
    rng = np.random.default_rng(seed)
    star = task.prior.sample(rng, n_people)
    x0 = task.sample_start(rng, n_people)
    learner = make_learner("gradient", task=task)
    theta0 = np.broadcast_to(learner.reset(), (n_people, task.dim)).copy()
    learner.reset(theta0)
    rec: dict[str, list[np.ndarray]] = {"x": [], "u_h": [], "u_r": [], "hat": []}

    def update(x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        rec["x"].append(np.array(x))
        rec["u_h"].append(np.array(u_h))
        rec["u_r"].append(np.array(u_r))
        rec["hat"].append(np.array(np.broadcast_to(learner.theta, (n_people, task.dim))))
        return learner.update(x, u_h, u_r)

    policy = task.robot_policy if robot else None
    teach(task, model, star, theta0, x0, update, rng, n_corrections, robot_policy=policy)
    k = np.repeat(np.arange(n_corrections), n_people)
    person = np.tile(np.arange(n_people), n_corrections)
    return Corrections(
        task,
        np.concatenate(rec["x"]),
        np.concatenate(rec["u_h"]),
        np.concatenate(rec["u_r"]),
        np.tile(star, (n_corrections, 1)),
        np.concatenate(rec["hat"]),
        k,
        person,
        person,
        [f"person {i}" for i in range(n_people)],
    )


def mean_deviation(data: Corrections) -> float:
    """Mean ‖u_H − u*‖ / a_max over the corrections (u* the eq. M6 teacher's choice)."""
    from strol_gym.benchmarks.sessions.fitting import teacher_choice

    a = np.asarray(data.task.action_bound)
    return float(np.linalg.norm((data.u_h - teacher_choice(data)) / a, axis=1).mean())


def matched_beta(task: Task, target: float, n_people: int, seed: int) -> float:
    """The Boltzmann β (σ 0) whose mean |u_H − u*| matches ``target`` (bisection on log β)."""
    lo, hi = math.log(0.1), math.log(1e5)
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        dev = mean_deviation(simulate_people(task, "boltzmann", n_people, seed, beta=math.exp(mid)))
        lo, hi = (mid, hi) if dev > target else (lo, mid)
    return math.exp(0.5 * (lo + hi))


def wilson(hits: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson 95 % interval of a binomial proportion (a coverage from ``n`` datasets)."""
    if n == 0:
        return (math.nan, math.nan)
    p = hits / n
    mid = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, mid - half), min(1.0, mid + half))


def dataset_intervals(
    human: str,
    data: Corrections,
    methods: Sequence[str],
    n_boot: int,
    seed: int,
) -> tuple[dict[str, float], dict[str, dict[str, tuple[float, float]]]]:
    """The MLE of ``human`` on ``data`` and its 95 % intervals by each of ``methods``
    (``fitting.INTERVALS``); the bootstrap ones share one set of ``n_boot`` resamples."""
    fam = family(human)
    data, _ = usable(fam, data)
    prep = prepare(fam, data)
    mle, _ = maximise(fam, prep)
    mle = {**mle, **fam.derive(mle)}
    out: dict[str, dict[str, tuple[float, float]]] = {}
    draws = jack = None
    for m in methods:
        if m == "sandwich":
            out[m] = sandwich_intervals(fam, prep, data, mle)
            continue
        if draws is None:
            draws = bootstrap_draws(fam, prep, data, mle, n_boot, np.random.default_rng(seed))
        if m == "bca" and jack is None:
            jack = jackknife_draws(fam, prep, data, mle)
        out[m] = bca_intervals(fam, draws, jack if m == "bca" else None, mle, len(data.people))
    return mle, out


def recovery(
    task: Task,
    human: str,
    truth: dict[str, Any],
    datasets: int,
    n_people: int,
    n_boot: int,
    seed: int = 0,
    robot: bool = True,
    methods: Sequence[str] = (DEFAULT_INTERVAL,),
) -> dict[str, Any]:
    """Per parameter, over ``datasets`` simulated datasets: the mean estimate and its bias, and
    per interval method the coverage of the truth (with its Wilson interval) and the mean
    width. The first method's figures are also the parameter's top-level ones."""
    params = dict(truth)  # the model's own, simulated with
    truth = {**truth, **{k: f(truth) for k, f in FITTED_AS.get(human, {}).items()}}
    est: dict[str, list[float]] = {k: [] for k in truth}
    cover: dict[str, dict[str, list[bool]]] = {m: {k: [] for k in truth} for m in methods}
    width: dict[str, dict[str, list[float]]] = {m: {k: [] for k in truth} for m in methods}
    for d in range(datasets):
        data = simulate_people(task, human, n_people, seed + 1000 * d, robot=robot, **params)
        mle, ivs = dataset_intervals(human, data, methods, n_boot, d)
        for k, v in truth.items():
            est[k].append(mle[k])
            for m in methods:
                lo, hi = ivs[m][k]
                cover[m][k].append(bool(lo <= v <= hi))
                width[m][k].append(hi - lo)
    out = {}
    for k, v in truth.items():
        per: dict[str, dict[str, Any]] = {}
        for m in methods:
            hits = int(np.sum(cover[m][k]))
            per[m] = {
                "coverage": hits / datasets,
                "coverage_ci95": wilson(hits, datasets),
                "mean_ci_width": float(np.mean(width[m][k])),
                "median_ci_width": float(np.median(width[m][k])),
            }
        bias = float(np.mean(est[k]) - v)
        first = per[methods[0]]
        out[k] = {
            "truth": v,
            "mean_estimate": float(np.mean(est[k])),
            "sd_estimate": float(np.std(est[k], ddof=1)) if datasets > 1 else math.nan,
            "bias": bias,
            "mean_ci_width": first["mean_ci_width"],
            "coverage": first["coverage"],
            "bias_ok": abs(bias) < first["mean_ci_width"] / 4,
            "datasets": datasets,
            "methods": per,
        }
    return out


def selection(
    task: Task,
    scenarios: dict[str, tuple[str, dict[str, Any]]],
    datasets: int,
    n_people: int,
    candidates: Sequence[str] = CANDIDATES,
    seed: int = 0,
    folds: int = 5,
    robot: bool = True,
) -> tuple[dict[str, dict[str, int]], dict[str, dict[str, int]]]:
    """Confusion counts (scenario -> model chosen -> datasets) under the parsimony rule
    (``fitting.select``) and, for comparison, by the highest held-out log-likelihood alone."""
    rule: dict[str, dict[str, int]] = {}
    plain: dict[str, dict[str, int]] = {}
    for label, (human, params) in scenarios.items():
        rule[label] = dict.fromkeys(candidates, 0)
        plain[label] = dict.fromkeys(candidates, 0)
        for d in range(datasets):
            data = simulate_people(
                task, human, n_people, seed + 7919 * (d + 1), robot=robot, **params
            )
            fits = {c: fit(c, data, n_boot=0, folds=folds, seed=d) for c in candidates}
            chosen = select(fits)
            rule[label][chosen.chosen] += 1
            plain[label][chosen.by_heldout] += 1
    return rule, plain


def _pct(x: float) -> str:
    return f"{100 * x:.0f}"


def markdown(rec: dict[str, dict], conf: dict[str, dict[str, int]], meta: dict) -> str:
    """The recovery table (one row per model × parameter, a coverage column per interval
    method with its Wilson 95 % interval) and the confusion matrix."""
    methods = list(
        dict.fromkeys(m for params in rec.values() for r in params.values() for m in r["methods"])
    )
    head = " | ".join(f"{m} coverage [Wilson 95 %] · mean width (median)" for m in methods)
    lines = [
        f"| model | parameter | truth | datasets | mean estimate | bias | sd | {head} | "
        "\\|bias\\| < width/4 |",
        "|---|---|---|---|---|---|---|" + "---|" * len(methods) + "---|",
    ]
    for human, params in rec.items():
        for k, r in params.items():
            cells = []
            for m in methods:
                c = r["methods"].get(m)
                if c is None:
                    cells.append("–")
                    continue
                lo, hi = c["coverage_ci95"]
                flag = "**" if c["coverage"] < 0.8 else ""
                median = c.get("median_ci_width", math.nan)
                cells.append(
                    f"{flag}{_pct(c['coverage'])} %{flag} [{_pct(lo)}, {_pct(hi)}] · "
                    f"{c['mean_ci_width']:.3g} ({median:.3g})"
                )
            lines.append(
                f"| {human} | {k} | {r['truth']:g} | {r['datasets']} | {r['mean_estimate']:.3g} | "
                f"{r['bias']:+.3g} | {r['sd_estimate']:.3g} | " + " | ".join(cells) + " | "
                f"{'yes' if r['bias_ok'] else 'no'} |"
            )
    plain = meta.get("confusion_heldout_only") or {}
    for title, table in (("parsimony rule", conf), ("highest held-out alone", plain)):
        if not table:
            continue
        cands = list(next(iter(table.values())))
        lines += [
            "",
            f"| data \\ chosen ({title}) | " + " | ".join(cands) + " |",
            "|---|" + "---|" * len(cands),
        ]
        for label, counts in table.items():
            lines.append(f"| {label} | " + " | ".join(str(counts[c]) for c in cands) + " |")
    lines += ["", f"{ {k: v for k, v in meta.items() if k != 'confusion_heldout_only'} }"]
    return "\n".join(lines) + "\n"


def merge(folders: Sequence[str]) -> tuple[dict[str, dict], dict[str, dict[str, int]], dict]:
    """The recovery and confusion of several runs' ``recovery.json`` (a later run's figures
    win; its interval methods join an earlier run's for the same datasets)."""
    rec: dict[str, dict] = {}
    conf: dict[str, dict[str, int]] = {}
    meta: dict[str, Any] = {"runs": []}
    for folder in folders:
        got = json.loads((Path(folder) / "recovery.json").read_text())
        for human, params in got.get("recovery", {}).items():
            for k, r in params.items():  # a later run's methods join an earlier run's
                old = rec.setdefault(human, {}).get(k)
                methods = {**old["methods"], **r["methods"]} if old else r["methods"]
                rec[human][k] = {**r, "methods": methods}
        conf.update(got.get("confusion", {}))
        plain = got.get("confusion_heldout_only", {})
        meta.setdefault("confusion_heldout_only", {}).update(plain)
        skip = ("recovery", "confusion", "confusion_heldout_only")
        meta["runs"].append({k: v for k, v in got.items() if k not in skip})
    return rec, conf, meta


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--task", default="robot")
    p.add_argument("--datasets", type=int, default=20)
    p.add_argument("--people", type=int, default=12)
    p.add_argument("--bootstrap", type=int, default=200)
    p.add_argument("--models", default=",".join(RECOVERY))
    p.add_argument(
        "--intervals",
        default=DEFAULT_INTERVAL,
        help=f"comma-separated interval methods to measure ({', '.join(INTERVALS)})",
    )
    p.add_argument("--no-selection", action="store_true")
    p.add_argument("--merge", nargs="+", metavar="DIR", help="only merge runs' recovery.json")
    p.add_argument("--out", default="results/fit-recovery")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.merge:
        write_text_atomic(out / "recovery.md", markdown(*merge(args.merge)))
        print(f"wrote {out / 'recovery.md'}")
        return 0
    methods = [m for m in args.intervals.split(",") if m]
    for m in methods:
        if m not in INTERVALS:
            p.error(f"--intervals: {m!r} is not one of {', '.join(INTERVALS)}")
    task = make_task(args.task)
    t0 = time.perf_counter()
    rec: dict[str, Any] = {}
    conf: dict[str, dict[str, int]] = {}
    meta: dict[str, Any] = {
        "task": args.task,
        "datasets": args.datasets,
        "people": args.people,
        "bootstrap": args.bootstrap,
        "intervals": methods,
    }

    def write() -> None:
        meta["seconds"] = round(time.perf_counter() - t0, 1)
        write_text_atomic(
            out / "recovery.json",
            json.dumps({"recovery": rec, "confusion": conf, **meta}, indent=2) + "\n",
        )

    for human in [m for m in args.models.split(",") if m]:
        t = time.perf_counter()
        rec[human] = recovery(
            task,
            human,
            RECOVERY[human],
            args.datasets,
            args.people,
            args.bootstrap,
            methods=methods,
        )
        print(human, json.dumps(rec[human]), f"{time.perf_counter() - t:.0f} s", flush=True)
        write()
    if not args.no_selection:
        target = mean_deviation(simulate_people(task, "nominal", args.people, 99, sigma=0.35))
        beta = matched_beta(task, target, args.people, 99)
        meta["matched_beta"] = beta
        scen = dict(SELECTION)
        scen["boltzmann (matched)"] = ("boltzmann", {"sigma": 0.0, "beta": beta})
        rule, plain = selection(task, scen, args.datasets, args.people)
        conf.update(rule)
        meta["confusion_heldout_only"] = plain
        print("confusion", json.dumps(conf), "held-out only", json.dumps(plain), flush=True)
        print(f"matched β {beta:.4g}", flush=True)
    write()
    write_text_atomic(out / "recovery.md", markdown(rec, conf, meta))
    print(f"wrote {out / 'recovery.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
