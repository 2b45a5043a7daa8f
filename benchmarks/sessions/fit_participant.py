"""``strol-bench fit-participant LOGS --out FILE``: fit the study population (StROL-Study-v2's
default participant, ``strol_gym.envs.study.population``) to imported user-study logs.

LOGS is a folder written by ``strol-bench import-study`` (one update per correction). Per
person (the header's ``extra["user"]``), from what the logs identify (the data card,
docs/study.md):

- **corrections per session**: per-Task means over every session, and the person's
  multiplier r = its corrections / the Task means over its sessions; the between-person sd of
  log r with the Poisson part taken out (var(log r) − mean 1/expected);
- **size**: the mean and the within-person sd of a correction's log displacement (a_max units,
  Tasks 1-3) and log rotation (Tasks 2-3);
- **aim**: τ such that corrections drawn by the population's model
  (``population.draw_corrections``) at the person's own poses, with its own sizes, have the
  person's median cos(u_H, θ*'s best correction); a fixed grid and fixed seeds;
- **when it is done**: per session, with the last correction at share s of the path, the
  person watched (1 − s)/s of the path time before it; the person's mean log of that.

The population is a normal on each log scale over the people; its 95 % intervals resample
people (``--bootstrap``); leave-one-person-out: each person's own value under the normal
fitted to the others (held-out log-likelihood, and whether it falls in the others' 5-95 %
range). Writes FILE (JSON: the estimates, intervals, held-out checks, the priors not fitted,
the source, command and date) and FILE with ``.md``.
"""

from __future__ import annotations

import argparse
import datetime
import math
import sys
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.replay_folder import find_logs
from strol_gym.benchmarks.sessions.study_card import _records
from strol_gym.envs.study.population import (
    FITTED,
    FORMAT,
    PRIORS,
    best_correction,
    cosine,
    draw_corrections,
)
from strol_gym.files import check_output, write_json_atomic, write_text_atomic
from strol_gym.tasks.study import StudyTask
from strol_gym.wrappers.session_log import read_session, session_task

AIM_GRID = np.geomspace(0.02, 20.0, 80)
"""τ values the aim is matched on (the median cosine falls monotonically along it)."""
AIM_DRAWS = 16
"""Draws per logged correction when matching τ."""
FIT_SEED = 39_000
SHARE_CLIP = (0.02, 0.98)
"""A last correction's path share is clipped here before (1 − s)/s (a share of 1 or 0 would
give an infinite log)."""
BOOTSTRAP = 1000


@dataclass
class Session:
    """One session as the statistics see it: who, which Task and learner, its corrections'
    displacement (a_max units), rotation (a_max units), cos to θ*'s best, start share of
    the path, and the count (empty and one-pose corrections included, as the card counts)."""

    person: str
    task: int
    learner: str
    count: int
    size: list[float] = field(default_factory=list)
    turn: list[float] = field(default_factory=list)
    cos: list[float] = field(default_factory=list)
    share: list[float] = field(default_factory=list)
    best: list[np.ndarray] = field(default_factory=list)
    """θ*'s steepest ascent at each correction's pose, a_max units (for the aim's match)."""


def correction_sizes(task: StudyTask, u: np.ndarray, rotation_rad: float) -> tuple[float, float]:
    """(displacement, rotation) of a correction in a_max units (Task 1's rotation: NaN)."""
    size = float(np.linalg.norm(np.asarray(u)[:3])) / task.pos_step
    turn = rotation_rad / task.ang_step if task.oriented else math.nan
    return size, turn


def read_sessions(folder: str | Path) -> list[Session]:
    """Every session of an imported folder (``strol-bench import-study``)."""
    out = []
    for path in find_logs(folder):
        session = read_session(path)
        task = session_task(session)
        if not isinstance(task, StudyTask):
            raise ValueError(f"{path}: fit-participant reads Study sessions, not {task.task_id}")
        extra = session.header.get("extra") or {}
        if "user" not in extra or "study_task" not in extra:
            raise ValueError(f"{path}: not an imported study session (no extra user/study_task)")
        recs = _records(path)
        ep = next(r for r in recs if r["type"] == "episode")
        star = np.asarray(ep["theta_star"], dtype=np.float64)
        s = Session(
            str(extra["user"]), int(extra["study_task"]), session.header["learner"],
            int(ep["corrections_logged"]),
        )  # fmt: skip
        for c in (r for r in recs if r["type"] == "correction"):
            x, u = np.asarray(c["x"], dtype=np.float64), np.asarray(c["u_h"], dtype=np.float64)
            size, turn = correction_sizes(task, u, math.radians(c["rotation_deg"]))
            best = best_correction(task, star, x)
            s.size.append(size)
            s.turn.append(turn)
            s.cos.append(float(cosine(u / task.action_bound, best)[0]))
            s.share.append(c["path_sample"] / c["path_samples"])
            s.best.append(best)
        out.append(s)
    if not out:
        raise ValueError(f"{folder}: no session logs")
    return out


def _logs(values: list[float]) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64)
    return np.log(v[np.isfinite(v) & (v > 0)])


def aim_of(sessions: list[Session], size: float, sw: float, turn: float, tw: float, seed: int):
    """τ whose draws at the person's poses have the person's median cosine (grid-matched)."""
    real = np.nanmedian([c for s in sessions for c in s.cos])
    groups: dict[int, list[np.ndarray]] = defaultdict(list)
    for s in sessions:
        groups[len(s.best[0]) if s.best else 0] += s.best
    medians = []
    for k, tau in enumerate(AIM_GRID):
        rng = np.random.default_rng([seed, k])
        cos = []
        for rows in (np.repeat(np.array(b), AIM_DRAWS, axis=0) for a, b in groups.items() if a):
            u = draw_corrections(
                rows, rng, aim=tau, size=size, size_within=sw, turn=turn, turn_within=tw
            )
            cos.append(cosine(u, rows))
        medians.append(np.nanmedian(np.concatenate(cos)))
    med = np.asarray(medians)
    # the median cosine falls along the grid: interpolate τ at the person's median
    if real >= med[0]:
        return float(AIM_GRID[0])
    if real <= med[-1]:
        return float(AIM_GRID[-1])
    order = np.argsort(med)
    return float(np.exp(np.interp(real, med[order], np.log(AIM_GRID)[order])))


@dataclass
class Person:
    """One person's own values (the between-person distribution's data)."""

    name: str
    size_log: float
    size_resid: np.ndarray
    turn_log: float
    turn_resid: np.ndarray
    aim_log: float
    linger_log: float
    counts: list[tuple[int, int]]
    """(Task, corrections) per session."""


def person_values(sessions: list[Session]) -> list[Person]:
    """Each person's values (module docstring), people in name order."""
    by: dict[str, list[Session]] = defaultdict(list)
    for s in sessions:
        by[s.person].append(s)
    people = []
    for i, name in enumerate(sorted(by, key=lambda n: (len(n), n))):
        ss = by[name]
        sz = _logs([v for s in ss for v in s.size])
        tn = _logs([v for s in ss for v in s.turn])
        if not len(sz) or not len(tn):
            raise ValueError(f"person {name}: needs corrections on Task 1 and on Tasks 2-3")
        size, turn = float(sz.mean()), float(tn.mean())
        sw, tw = float(sz.std()), float(tn.std())
        aim = aim_of(ss, math.exp(size), sw, math.exp(turn), tw, FIT_SEED + i)
        lingers = []
        for s in ss:
            if s.share:
                last = float(np.clip(max(s.share), *SHARE_CLIP))
                lingers.append(math.log((1.0 - last) / last))
        people.append(
            Person(
                name, size, sz - size, turn, tn - turn, math.log(aim),
                float(np.mean(lingers)) if lingers else math.nan,
                [(s.task, s.count) for s in ss],
            )
        )  # fmt: skip
    return people


def population(people: list[Person]) -> dict[str, Any]:
    """The between-person estimates of ``people`` (``population.FITTED`` and count_mean)."""
    out: dict[str, Any] = {}
    for key in ("size", "turn", "aim", "linger"):
        v = np.array([getattr(p, f"{key}_log") for p in people])
        v = v[np.isfinite(v)]
        out[f"{key}_log_mean"] = float(v.mean())
        out[f"{key}_log_sd"] = float(v.std(ddof=1)) if len(v) > 1 else 0.0
    for key in ("size", "turn"):
        resid = np.concatenate([getattr(p, f"{key}_resid") for p in people])
        out[f"{key}_within"] = float(np.sqrt(np.mean(resid**2)))
    per_task: dict[int, list[int]] = defaultdict(list)
    for p in people:
        for t, c in p.counts:
            per_task[t].append(c)
    means = {t: float(np.mean(per_task[t])) for t in (1, 2, 3) if per_task[t]}
    if len(means) < 3:
        raise ValueError("the fit needs sessions of all three Tasks")
    logs, noise = [], []
    for p in people:
        expected = sum(means[t] for t, _ in p.counts)
        made = sum(c for _, c in p.counts)
        if made > 0 and expected > 0:
            logs.append(math.log(made / expected))
            noise.append(1.0 / made)
    var = float(np.var(logs, ddof=1)) if len(logs) > 1 else 0.0
    out["count_person_sd"] = math.sqrt(max(0.0, var - float(np.mean(noise))))
    out["count_mean"] = means
    return out


def _normal_logpdf(x: float, mean: float, sd: float) -> float:
    sd = max(sd, 1e-6)
    return -0.5 * ((x - mean) / sd) ** 2 - math.log(sd * math.sqrt(2.0 * math.pi))


def leave_one_out(people: list[Person]) -> dict[str, Any]:
    """Each person's own value under the normal fitted to the other people: the summed
    held-out log density and how many fall in the others' 5-95 % range."""
    out: dict[str, Any] = {}
    for key in ("size", "turn", "aim", "linger"):
        ll, inside, n = 0.0, 0, 0
        for i, p in enumerate(people):
            v = getattr(p, f"{key}_log")
            if not math.isfinite(v):
                continue
            rest = population([q for j, q in enumerate(people) if j != i])
            m, sd = rest[f"{key}_log_mean"], rest[f"{key}_log_sd"]
            ll += _normal_logpdf(v, m, sd)
            inside += abs(v - m) <= 1.645 * sd
            n += 1
        out[key] = {"heldout_loglik": ll, "inside_90": f"{inside}/{n}"}
    err = []
    for i, p in enumerate(people):
        rest = population([q for j, q in enumerate(people) if j != i])
        for t in (1, 2, 3):
            mine = [c for tt, c in p.counts if tt == t]
            if mine:
                err.append(np.mean(mine) - rest["count_mean"][t])
    out["count"] = {
        "heldout_mean_error": float(np.mean(err)),
        "heldout_rms_error": float(np.sqrt(np.mean(np.square(err)))),
        "note": "a held-out person's mean corrections per session on a Task minus the others' "
        "Task mean (the person's multiplier is what the sd describes)",
    }
    return out


def bootstrap(people: list[Person], n_boot: int, seed: int) -> dict[str, tuple[float, float]]:
    """Percentile 95 % intervals of every estimate, resampling people with replacement."""
    rng = np.random.default_rng(seed)
    draws: dict[str, list[float]] = defaultdict(list)
    for _ in range(n_boot):
        pick = rng.integers(0, len(people), len(people))
        est = population([people[i] for i in pick])
        for k in FITTED:
            draws[k].append(est[k])
        for t, v in est["count_mean"].items():
            draws[f"count_mean_{t}"].append(v)
    return {
        k: (float(np.percentile(v, 2.5)), float(np.percentile(v, 97.5))) for k, v in draws.items()
    }


def fit_participant(
    folder: str | Path, n_boot: int = BOOTSTRAP, seed: int = FIT_SEED, command: str = ""
) -> dict[str, Any]:
    """The fit file's JSON object (module docstring)."""
    sessions = read_sessions(folder)
    people = person_values(sessions)
    if len(people) < 3:
        raise ValueError(f"{folder}: a between-person fit needs at least 3 people")
    est = population(people)
    ci = bootstrap(people, n_boot, seed) if n_boot else {}

    def entry(name: str, value: float) -> dict[str, Any]:
        return {"estimate": value, "ci95": list(ci.get(name, (math.nan, math.nan)))}

    fitted: dict[str, Any] = {k: entry(k, est[k]) for k in FITTED}
    fitted["count_mean"] = {
        str(t): entry(f"count_mean_{t}", v) for t, v in est["count_mean"].items()
    }
    return {
        "format": FORMAT,
        "version": 1,
        "source": "the authors' user study (github.com/VT-Collab/StROL_RAL before d383bef), "
        "imported with strol-bench import-study",
        "command": command or "strol-bench fit-participant LOGS --out FILE",
        "date": datetime.date.today().isoformat(),
        "n_people": len(people),
        "n_sessions": len(sessions),
        "n_corrections": int(sum(len(s.size) for s in sessions)),
        "bootstrap": n_boot,
        "seed": seed,
        "units": "size and turn in a_max units (0.1 m, 0.3 rad); every *_log_* a natural log; "
        "aim τ: direction b̂ + τ z; linger: watched path time after the last correction over "
        "the path time before it",
        "fitted": fitted,
        "heldout": leave_one_out(people),
        "prior": {k: {**v, "status": "prior, not fitted"} for k, v in PRIORS.items()},
    }


def fit_markdown(fit: dict[str, Any]) -> str:
    """The fit as a table: estimates with intervals, the held-out checks, the priors."""

    def row(name: str, e: dict[str, Any], scale: str = "") -> str:
        lo, hi = e["ci95"]
        return f"| {name} | {e['estimate']:.3f} | [{lo:.3f}, {hi:.3f}] | {scale} |"

    f = fit["fitted"]
    lines = [
        f"Fitted to {fit['n_people']} people, {fit['n_sessions']} sessions, "
        f"{fit['n_corrections']} corrections ({fit['bootstrap']} bootstrap resamples of people).",
        "",
        "| parameter | estimate | 95 % CI | |",
        "|---|---|---|---|",
    ]
    for t in ("1", "2", "3"):
        lines.append(row(f"corrections per session, Task {t}", f["count_mean"][t]))
    for k in FITTED:
        scale = ""
        if k.endswith("_log_mean"):
            e = f[k]["estimate"]
            scale = f"median person {math.exp(e):.3f}"
        lines.append(row(k, f[k], scale))
    lines += ["", "Leave one person out:", ""]
    for k, v in fit["heldout"].items():
        lines.append(f"- {k}: " + ", ".join(f"{a} {b}" for a, b in v.items() if a != "note"))
    lines += ["", "Not fitted (prior):", ""]
    for k, v in fit["prior"].items():
        lines.append(f"- {k} = {v['value']} {v['unit']}: {v['status']}; {v['source']}")
    return "\n".join(lines) + "\n"


def add_parser(sub: Any) -> None:
    from strol_gym.benchmarks.args import positive_int

    p = sub.add_parser(
        "fit-participant",
        help="fit the study population (StROL-Study-v2's participant) to imported study logs",
        description="Fit the between-person distribution of the simulated study participant "
        "to a folder written by import-study: corrections per session, size, aim, when done; "
        "bootstrap over people, leave-one-person-out checks. Writes the fit file (JSON) and "
        "a markdown table beside it.",
    )
    p.add_argument("logs", help="a folder written by strol-bench import-study")
    p.add_argument("--out", required=True, help="the fit file to write (.json)")
    p.add_argument(
        "--bootstrap", type=positive_int("--bootstrap", 100_000, low=0), default=BOOTSTRAP
    )
    p.add_argument("--seed", type=positive_int("--seed", low=0), default=FIT_SEED)


def command(args: argparse.Namespace, parser: Any) -> int:
    if not Path(args.logs).is_dir():
        parser.error(
            f"LOGS must be a folder written by strol-bench import-study, got {args.logs!r}"
        )
    out = check_output(args.out, "--out")  # before the work: a FIFO, a device, a link
    check_output(out.with_suffix(".md"), "--out's table")
    cmd = f"strol-bench fit-participant LOGS --out {out.name} --bootstrap {args.bootstrap}"
    try:
        fit = fit_participant(args.logs, args.bootstrap, args.seed, cmd + f" --seed {args.seed}")
    except ValueError as e:
        print(f"strol-bench fit-participant: error: {e}", file=sys.stderr)
        return 2
    write_json_atomic(out, fit)
    text = fit_markdown(fit)
    write_text_atomic(out.with_suffix(".md"), text)
    print(text)
    print(f"wrote {out} and {out.with_suffix('.md')}")
    return 0


__all__ = ["Session", "add_parser", "command", "fit_participant", "read_sessions"]

if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers()
    add_parser(sub)
    ns = parser.parse_args(["fit-participant", *sys.argv[1:]])
    sys.exit(command(ns, parser))
