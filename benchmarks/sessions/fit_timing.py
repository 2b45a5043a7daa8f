"""``strol-bench fit-timing LOGS --out DIR``: when the real people corrected, given the robot.

Reads a folder of imported study sessions (``strol-bench import-study DIR --out LOGS --theta0
implied``: θ̂ before/after each correction where it is known), computes along each session the
shortfall of the robot's plan (``strol_gym.humans.timing``), fits the timing models on the
sessions of the ``--fit`` learners (One and MOF) and checks them on the held-out learner's
(``--heldout``, StROL): held-out log-likelihood of its correction times, and the StROL/One
count ratio the fit predicts along the logged paths against the real one, each with a
person-bootstrap interval. Writes ``DIR/timing.json``; prints a table.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.replay_folder import find_logs
from strol_gym.benchmarks.sessions.study_card import _records
from strol_gym.files import write_json_atomic
from strol_gym.humans import timing
from strol_gym.tasks.study import STUDY_TASKS, StudyTask
from strol_gym.wrappers.session_log import read_session

DT = 0.05
"""s per logged path sample (the authors' loop; their correction time is 0.05 s × samples)."""
BOOTSTRAP = 400
BOOT_SEED = 49


@functools.cache
def _task(number: int) -> StudyTask:
    """Study Task ``number`` (one object per process: the shortfall's unit is cached by it)."""
    return STUDY_TASKS[number]()


def read_timed(
    folder: str | Path, cap: float = timing.SHORTFALL_CAP
) -> tuple[list[timing.TimedSession], list[dict[str, Any]]]:
    """The sessions whose θ̂ is known along the path (their shortfall at most ``cap``), and a
    row per session skipped (why)."""
    out, skipped = [], []
    for path in find_logs(folder):
        session = read_session(path)
        extra = session.header.get("extra") or {}
        if "user" not in extra or "study_task" not in extra:
            raise ValueError(f"{path}: not an imported study session (no extra user/study_task)")
        recs = _records(path)
        ep = next(r for r in recs if r["type"] == "episode")
        corr = [r for r in recs if r["type"] == "correction"]
        learner, task = str(session.header["learner"]), int(extra["study_task"])
        hats = [ep.get("theta_hat0")] + [c.get("theta_hat_after") for c in corr]
        known = ep.get("theta_hat0_source", "").startswith(("implied", "reconstructed"))
        if not known or any(h is None for h in hats) or ep.get("path_samples") is None:
            skipped.append({"log": path.name, "why": "θ̂ along the path not known"})
            continue
        star = np.asarray(ep["theta_star"], dtype=np.float64)
        out.append(
            timing.TimedSession(
                person=str(extra["user"]),
                task=task,
                learner=learner,
                samples=int(ep["path_samples"]),
                events=np.array([int(c["path_sample"]) for c in corr], dtype=np.int64),
                shortfall=timing.shortfall(
                    _task(task), star, np.array(hats, dtype=np.float64), cap
                ),
            )
        )
    return out, skipped


def correction_samples(folder: str | Path) -> list[int]:
    """Logged poses of every correction of every session (empty and one-pose ones as the
    episode line counts them: 0 and 1)."""
    out: list[int] = []
    for path in find_logs(folder):
        recs = _records(path)
        ep = next(r for r in recs if r["type"] == "episode")
        out += [0] * int(ep.get("corrections_empty") or 0)
        out += [1] * int(ep.get("corrections_one_pose") or 0)
        seen = set()
        for c in recs:
            if c["type"] == "correction" and c["physical_correction"] not in seen:
                seen.add(c["physical_correction"])
                out.append(int(c["samples"]))
    return out


def ratio(sessions: list[timing.TimedSession], counts: np.ndarray, num: str, den: str) -> float:
    """Σ counts of learner ``num``'s sessions over Σ of ``den``'s."""
    a = sum(c for s, c in zip(sessions, counts, strict=True) if s.learner == num)
    b = sum(c for s, c in zip(sessions, counts, strict=True) if s.learner == den)
    return float(a / b) if b > 0 else math.nan


def evaluate(
    sessions: list[timing.TimedSession], fit_learners: tuple[str, ...], heldout: str
) -> dict[str, Any]:
    """Per model: fitted coefficients, held-out log L of ``heldout``'s sessions, and its
    predicted and real count ratio to One (module docstring)."""
    train = [s for s in sessions if s.learner in fit_learners]
    test = [s for s in sessions if s.learner == heldout]
    one = [s for s in sessions if s.learner == "one"]
    real = np.array([len(s.events) for s in test + one], dtype=np.float64)
    out: dict[str, Any] = {
        "sessions": {"fit": len(train), "heldout": len(test)},
        "real_ratio": ratio(test + one, real, heldout, "one"),
        "models": {},
    }
    for model in timing.MODELS:
        f = timing.fit(train, model, DT)
        pred = timing.predicted_counts(f, test + one)
        out["models"][model] = {
            "params": f.params,
            "fit_loglik": f.loglik,
            "heldout_loglik": timing.loglik(f, test) if test else math.nan,
            "heldout_events": int(sum(len(s.events) for s in test)),
            "predicted_ratio": ratio(test + one, pred, heldout, "one"),
            "predicted_heldout_count": float(sum(pred[: len(test)])),
        }
    return out


def bootstrap(
    sessions: list[timing.TimedSession],
    fit_learners: tuple[str, ...],
    heldout: str,
    reps: int = BOOTSTRAP,
    seed: int = BOOT_SEED,
) -> dict[str, Any]:
    """Person bootstrap: people resampled with replacement, the fit redone; the 95 % interval
    of the real ratio, of each model's predicted ratio and of the reactive model's held-out
    log L gain over ``wait`` (per held-out session)."""
    people = sorted({s.person for s in sessions})
    by = {p: [s for s in sessions if s.person == p] for p in people}
    rng = np.random.default_rng(seed)
    real: list[float] = []
    gain: list[float] = []
    pred: dict[str, list[float]] = {m: [] for m in timing.MODELS}
    for _ in range(reps):
        pick = rng.integers(0, len(people), len(people))
        sample = [s for i in pick for s in by[people[i]]]
        r = evaluate(sample, fit_learners, heldout)
        real.append(r["real_ratio"])
        for m in timing.MODELS:
            pred[m].append(r["models"][m]["predicted_ratio"])
        n = max(r["sessions"]["heldout"], 1)
        gain.append(
            (r["models"]["reactive"]["heldout_loglik"] - r["models"]["wait"]["heldout_loglik"]) / n
        )

    def ci(v: list[float]) -> list[float]:
        a = np.asarray(v, dtype=np.float64)
        a = a[np.isfinite(a)]
        return np.percentile(a, [2.5, 97.5]).tolist() if len(a) else [math.nan, math.nan]

    return {
        "reps": reps,
        "seed": seed,
        "real_ratio_ci95": ci(real),
        "predicted_ratio_ci95": {m: ci(v) for m, v in pred.items()},
        "heldout_gain_per_session_ci95": ci(gain),
    }


def leave_one_person_out(
    sessions: list[timing.TimedSession], fit_learners: tuple[str, ...]
) -> dict[str, float]:
    """Σ over people of the log L of their fit-learner sessions under a fit without them."""
    train = [s for s in sessions if s.learner in fit_learners]
    out = dict.fromkeys(timing.MODELS, 0.0)
    for p in sorted({s.person for s in train}):
        rest = [s for s in train if s.person != p]
        own = [s for s in train if s.person == p]
        for m in timing.MODELS:
            out[m] += timing.loglik(timing.fit(rest, m, DT), own)
    return out


def run(folder: str | Path, fit_learners: tuple[str, ...], heldout: str, reps: int) -> dict:
    sessions, skipped = read_timed(folder)
    if not any(s.learner in fit_learners for s in sessions):
        raise ValueError(f"LOGS {folder}: no session of {', '.join(fit_learners)} with θ̂ known")
    res = evaluate(sessions, fit_learners, heldout)
    res["skipped"] = skipped
    res["correction_samples"] = correction_samples(folder)
    samples: dict[int, list[int]] = {}
    for s in sessions:
        samples.setdefault(s.task, []).append(s.samples)
    res["_samples"] = samples
    res["doubled_budget"] = doubled_budget(sessions, fit_learners)
    res["fit_learners"] = list(fit_learners)
    res["heldout"] = heldout
    res["dt"] = DT
    res["lopo_loglik"] = leave_one_person_out(sessions, fit_learners)
    res["bootstrap"] = bootstrap(sessions, fit_learners, heldout, reps)
    res["shortfall_unit"] = {
        str(t): timing.shortfall_unit(_task(t), _task(t).theta_star) for t in timing.TASKS
    }
    return res


def doubled_budget(
    sessions: list[timing.TimedSession], fit_learners: tuple[str, ...]
) -> dict[str, float]:
    """Per Task of ``timing.DOUBLED_TASKS``, the budget (s of the robot's motion) its sessions
    of ``fit_learners`` ended on: the median of the logged path time plus the path time before
    the last correction (the authors' Task 1 loop counted that twice, ``timing.doubled_end``)."""
    out = {}
    for t in timing.DOUBLED_TASKS:
        ends = [
            s.samples + (int(s.events[-1]) if len(s.events) else 0)
            for s in sessions
            if s.task == t and s.learner in fit_learners
        ]
        if ends:
            out[str(t)] = float(np.median(ends)) * DT
    return out


SHIPPED = "impatient"
"""The model the population ships (``--ship``): the best leave-one-person-out log-likelihood
on the One and MOF sessions (docs/study-physics.md)."""


def population_fit(
    res: dict[str, Any],
    sessions_samples: dict[int, list[int]],
    model: str = SHIPPED,
    doubled: bool = True,
) -> dict:
    """The shipped excerpt (``population.TIMING_FILE``): per Task ``model``'s (a_Task, b, c[,
    d]) and the mean logged path time of its sessions; with ``doubled``, the budget of the
    Tasks whose session ended on the authors' doubled count (``doubled_budget``)."""
    p = res["models"][model]["params"]
    terms = timing.TERMS[: 2 + ("impatience" in timing.MODELS[model])]
    return {
        "format": "strol-timing-fit",
        "version": 1,
        "model": model,
        "source": "the authors' user study (github.com/VT-Collab/StROL_RAL before d383bef), "
        "imported with strol-bench import-study DATA --out LOGS --theta0 implied "
        "--authors-ghat GDIR (StROL's θ̂ under the paper's ĝ, λ = 0.25)",
        "command": "strol-bench fit-timing LOGS --out DIR --bootstrap 400 --write-fit "
        "timing_fit.json",
        "fit_learners": res["fit_learners"],
        "units": "rate per s of the robot's logged path (dt = 0.05 s per sample); shortfall: "
        "regret of the plan of θ̂ over the median regret of θ̂ uniform in [-1, 1]^d; wait: "
        "log(1 + s since the last correction)"
        + ("; hazard [a, b, c, d]: exp(a + b s + (c + d s) wait)" if len(terms) > 2 else ""),
        "hazard": {str(t): [p[f"rate_task{t}"], *(p[k] for k in terms)] for t in timing.TASKS},
        "path_time": {str(t): float(np.mean(v)) * DT for t, v in sorted(sessions_samples.items())},
        **(
            {
                "doubled_budget": res["doubled_budget"],
                "doubled_budget_source": "the authors' Task 1 loop added the robot's motion "
                "since the last correction to its elapsed time again at each correction: a "
                "session ended when the motion plus the motion before its last correction "
                "reached this budget (s; the median over the fitted learners' sessions of that "
                "Task); without an entry a Task's person watches path_time s",
            }
            if doubled
            else {}
        ),
        "rise": float(np.median(res["correction_samples"])) * DT,
        "rise_source": "the median logged poses per correction (every learner) x 0.05 s: the "
        "authors' loop logged a pose at each new force maximum, so a push's force rose for "
        "about that long; the simulated push's force rises (and falls) over it",
        "heldout": {
            "learner": res["heldout"],
            "loglik": {m: r["heldout_loglik"] for m, r in res["models"].items()},
            "predicted_ratio": res["models"][SHIPPED]["predicted_ratio"],
            "real_ratio": res["real_ratio"],
        },
    }


def table(res: dict[str, Any]) -> list[str]:
    b = res["bootstrap"]
    lo, hi = b["real_ratio_ci95"]
    lines = [
        f"fit on {', '.join(res['fit_learners'])} ({res['sessions']['fit']} sessions); "
        f"held out {res['heldout']} ({res['sessions']['heldout']} sessions)",
        f"real {res['heldout']}/one count ratio {res['real_ratio']:.3f} "
        f"[{lo:.3f}, {hi:.3f}] (person bootstrap, {b['reps']} reps)",
        "model     params                                   LOPO logL  held-out logL  ratio [95%]",
    ]
    for m, r in res["models"].items():
        p = " ".join(f"{v:+.3f}" for v in r["params"].values())
        plo, phi = b["predicted_ratio_ci95"][m]
        lines.append(
            f"{m:9s} {p:40s} {res['lopo_loglik'][m]:9.1f}  {r['heldout_loglik']:13.1f}  "
            f"{r['predicted_ratio']:.3f} [{plo:.3f}, {phi:.3f}]"
        )
    g = b["heldout_gain_per_session_ci95"]
    lines.append(f"reactive − wait held-out logL per session, 95 %: [{g[0]:.3f}, {g[1]:.3f}]")
    return lines


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "fit-timing",
        help="fit when the study's people corrected, given the robot's plan; check on a "
        "held-out learner",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    p.add_argument("logs", help="imported study sessions (import-study --theta0 implied)")
    p.add_argument("--out", required=True, help="folder for timing.json")
    p.add_argument("--fit", default="one,mof", help="learners fitted on (one,mof)")
    p.add_argument("--heldout", default="strol", help="the held-out learner (strol)")
    p.add_argument("--bootstrap", type=int, default=BOOTSTRAP, help="person-bootstrap reps")
    p.add_argument(
        "--write-fit",
        default=None,
        help="also write the population's timing file here (population.TIMING_FILE's format)",
    )
    p.add_argument(
        "--ship",
        choices=tuple(timing.MODELS),
        default=SHIPPED,
        help=f"the model --write-fit writes ({SHIPPED})",
    )
    p.add_argument(
        "--no-doubled-end",
        action="store_true",
        help="--write-fit leaves out the budget of the Tasks whose session ended on the "
        "authors' doubled count (Task 1; with it their person is done there, not after "
        "path_time)",
    )


def command(args: Any, parser: Any) -> int:
    fit_learners = tuple(v for v in str(args.fit).split(",") if v)
    if not fit_learners:
        parser.error("--fit: name at least one learner, e.g. one,mof")
    if not 1 <= int(args.bootstrap) <= 100_000:
        parser.error(f"--bootstrap must be in 1..100000, got {args.bootstrap}")
    res = run(args.logs, fit_learners, str(args.heldout), int(args.bootstrap))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    samples = res.pop("_samples")
    write_json_atomic(out / "timing.json", res)
    if args.write_fit:
        fit = population_fit(res, samples, args.ship, not args.no_doubled_end)
        write_json_atomic(Path(args.write_fit), fit)
    print("\n".join(table(res)))
    return 0


__all__ = [
    "add_parser",
    "bootstrap",
    "command",
    "doubled_budget",
    "evaluate",
    "read_timed",
    "run",
]
