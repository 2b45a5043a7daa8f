"""How close are the simulated study participants to the twelve real people? The fit measured,
not asserted (docs/study.md, "The fitted participant").

Runs 60 s study sessions (One, MOF and StROL learning, the real study's learners; seeds
39100+, outside the study's) for v1's participant on StROL-Study-v1 and for the fitted
population on StROL-Study-v2, reads every correction the env reports, and compares per Task,
statistic by statistic, with the imported real sessions (``strol-bench import-study``): the
two-sample Kolmogorov-Smirnov distance, with a person-level bootstrap band (real people and
simulated users resampled with replacement, 95 % percentile band). Also counts rebounds (a
correction starting < 0.3 s after the last ended, opposite to it) and the reflexes that
tripped while the participant pushed (a push lost: the arm braked, no correction).

    python -m lab.study.participant_check LOGS --users 12 --out DIR

Writes DIR/distances.json and DIR/distances.md (aggregates only).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import warnings
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from strol_gym.benchmarks.sessions.fit_participant import (
    Session,
    correction_sizes,
    read_sessions,
)
from strol_gym.envs.study.population import best_correction, cosine
from strol_gym.files import write_text_atomic
from strol_gym.tasks.study import StudyTask

SEED = 39_100
LEARNERS = ("one", "mof", "strol")
"""The real study's learners (One, MOF, StROL)."""
REBOUND_GAP = 0.3
"""s: a correction starting sooner than this after the last one ended, opposite to it, is a
rebound of the push, not a person's new correction."""
STATISTICS = ("count", "size", "turn", "cos", "share")
LABELS = {
    "count": "corrections per session",
    "size": "displacement (a_max)",
    "turn": "rotation (a_max)",
    "cos": "cos(u_H, θ*'s best)",
    "share": "start along the path (share)",
}
WHO = {
    "v1": ("StROL-Study-v1", "observer", "v1's participant (v1)"),
    "v2": ("StROL-Study-v2", "fitted", "fitted population (v2)"),
}
BOOTSTRAP = 500


def _rotation(task: Any, x: np.ndarray, u: np.ndarray) -> float:
    """The angle (rad) of the turn from pose x to x + u (Tasks 2-3)."""
    from strol_gym.tasks.study import rpy_to_mat

    r0, r1 = rpy_to_mat(x[3:6]), rpy_to_mat(x[3:6] + u[3:6])
    c = (np.trace(r1 @ r0.T) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def simulate(who: str, task: int, learner: str, seed: int) -> dict[str, Any]:
    """One 60 s session: its :class:`Session` (person = the seed), rebounds and reflexes."""
    import gymnasium as gym

    import strol_gym  # noqa: F401  (registers the envs)
    from strol_gym import checks
    from strol_gym.learners.registry import make_learner
    from strol_gym.wrappers.online_learning import OnlineLearningWrapper, learning_env

    warnings.simplefilter("ignore")
    env_id, participant, _ = WHO[who]
    # σ = 0.25 for v1's observer (its hand's noise); the fitted person's noise is fitted
    person: dict[str, Any] = {"name": participant}
    if participant != "fitted":
        person["sigma"] = 0.25
    task_arg: Any = f"study-task{task}-v1" if who == "v1" else task
    env = gym.make(env_id, task=task_arg, person=person)
    t = learning_env(env).task
    if not isinstance(t, StudyTask):
        raise TypeError(f"{env_id} built a {type(t).__name__}, not a study Task")
    env = OnlineLearningWrapper(env, make_learner(learner, task=t))
    env.reset(seed=seed)
    zero = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
    records, truncated, info = [], False, {}
    human = env.unwrapped.person  # type: ignore[attr-defined]
    push_reflexes = 0
    while not truncated:
        _, _, _, truncated, info = env.step(zero)
        push_reflexes += bool(info.get("reflex")) and human.phase != "idle"
        if info["is_correction"]:
            records.append(info["correction_record"])
    duration = float(info["time"])
    done = getattr(human, "done_at", None)
    end = min(duration, done) if done is not None else duration
    star = np.asarray(t.theta_star, dtype=np.float64)
    s = Session(str(seed), task, learner, len(records))
    pushed, rebounds, last = 0.0, 0, None
    total_push = sum(r["end_time"] - r["start_time"] for r in records)
    for r in records:
        x, u = np.asarray(r["state"]), np.asarray(r["u_h"])
        turn = _rotation(t, x, u) if t.oriented else math.nan
        size, turn = correction_sizes(t, u, turn)
        best = best_correction(t, star, x)
        s.size.append(size)
        s.turn.append(turn)
        s.cos.append(float(cosine(u / t.action_bound, best)[0]))
        s.share.append((r["start_time"] - pushed) / max(end - total_push, 1e-9))
        s.best.append(best)
        pushed += r["end_time"] - r["start_time"]
        if last is not None and r["start_time"] - last["end_time"] < REBOUND_GAP:
            rebounds += float(np.dot(u, last["u_h"])) < 0.0
        last = r
    env.close()
    a_max = np.asarray(t.action_bound, dtype=np.float64)
    reads = [np.asarray(r["u_h"]) / a_max for r in records]
    meant = list(getattr(human, "intended", []))
    return {
        "session": s,
        "sizes": {
            "read": [_pos_rot(u) for u in reads],
            "intended": [_pos_rot(u) for u in meant],
        },
        "rebounds": rebounds,
        "reflexes": push_reflexes,
        "correction_time": float(info["correction_time"]),
    }


def _pos_rot(u: np.ndarray) -> tuple[float, float]:
    """|position part|, |rotation part| of a correction in a_max units (rotation 0 in Task 1)."""
    return float(np.linalg.norm(u[:3])), float(np.linalg.norm(u[3:]))


def read_scale(results: Sequence[dict[str, Any]]) -> list[float] | None:
    """(position, rotation): the median read u_H over the median intended correction (a_max
    units) of sessions' pushes (``FittedParticipant.intended``), what v2's arm makes of what a
    person means (``FittedPopulationModel``'s ``read_scale``); None without intended pushes.
    A rotation without turns (Task 1) is 1."""
    read = np.array([v for r in results for v in r["sizes"]["read"]]).reshape(-1, 2)
    meant = np.array([v for r in results for v in r["sizes"]["intended"]]).reshape(-1, 2)
    if not len(read) or not len(meant):
        return None
    out = []
    for axis in (0, 1):
        m = float(np.median(meant[:, axis]))
        out.append(float(np.median(read[:, axis])) / m if m > 0 else 1.0)
    return out


def _values(sessions: Sequence[Session], stat: str) -> dict[str, list[float]]:
    """Per person, the statistic's values (a session's count, or each correction's)."""
    out: dict[str, list[float]] = {}
    for s in sessions:
        vals = [float(s.count)] if stat == "count" else list(getattr(s, stat))
        out.setdefault(s.person, []).extend(v for v in vals if math.isfinite(v))
    return out


def ks(a: dict[str, list[float]], b: dict[str, list[float]]) -> float:
    va = [v for vs in a.values() for v in vs]
    vb = [v for vs in b.values() for v in vs]
    if not va or not vb:
        return math.nan
    return float(stats.ks_2samp(va, vb).statistic)


def distance(
    real: Sequence[Session], sim: Sequence[Session], stat: str, n_boot: int, seed: int
) -> dict[str, Any]:
    """KS(real, sim) of ``stat`` and its 95 % band, people resampled on both sides."""
    a, b = _values(real, stat), _values(sim, stat)
    rng = np.random.default_rng(seed)
    ka, kb = list(a), list(b)
    draws = []
    for _ in range(n_boot):
        ra = {str(i): a[ka[j]] for i, j in enumerate(rng.integers(0, len(ka), len(ka)))}
        rb = {str(i): b[kb[j]] for i, j in enumerate(rng.integers(0, len(kb), len(kb)))}
        draws.append(ks(ra, rb))
    band = np.nanpercentile(draws, [2.5, 97.5]) if draws else [math.nan, math.nan]
    va = [v for vs in a.values() for v in vs]
    vb = [v for vs in b.values() for v in vs]
    return {
        "ks": ks(a, b),
        "band": [float(band[0]), float(band[1])],
        "real_median": float(np.median(va)) if va else math.nan,
        "sim_median": float(np.median(vb)) if vb else math.nan,
        "real_mean": float(np.mean(va)) if va else math.nan,
        "sim_mean": float(np.mean(vb)) if vb else math.nan,
    }


def _job(args: tuple[str, int, str, int]) -> dict[str, Any]:
    return simulate(*args)


def run(
    logs: str | Path,
    users: int,
    out: str | Path,
    jobs: int = 1,
    who: Sequence[str] = ("v1", "v2"),
    tasks: Sequence[int] = (1, 2, 3),
    n_boot: int = BOOTSTRAP,
) -> dict[str, Any]:
    """The comparison (module docstring); writes DIR/distances.json and .md."""
    real = read_sessions(logs)
    units = [
        (w, t, lr, SEED + u) for w in who for t in tasks for u in range(users) for lr in LEARNERS
    ]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            results = list(pool.map(_job, units))
    else:
        results = [_job(u) for u in units]
    result: dict[str, Any] = {"users": users, "learners": list(LEARNERS), "seed": SEED, "who": {}}
    for w in who:
        rs = [r for u, r in zip(units, results, strict=True) if u[0] == w]
        per: dict[str, Any] = {}
        for t in tasks:
            sim = [r["session"] for r in rs if r["session"].task == t]
            rt = [s for s in real if s.task == t]
            n_corr = sum(s.count for s in sim)
            reb = sum(r["rebounds"] for r in rs if r["session"].task == t)
            per[str(t)] = {
                "stats": {
                    st: distance(rt, sim, st, n_boot, SEED + t)
                    for st in STATISTICS
                    if not (st == "turn" and t == 1)
                },
                "corrections": n_corr,
                "rebounds": reb,
                "rebound_share": reb / n_corr if n_corr else math.nan,
                "reflexes": sum(r["reflexes"] for r in rs if r["session"].task == t),
                "read_scale": read_scale([r for r in rs if r["session"].task == t]),
                "count_by_learner": {
                    lr: float(np.mean([s.count for s in sim if s.learner == lr])) for lr in LEARNERS
                },
                "real_count_by_learner": {
                    lr: float(np.mean([s.count for s in rt if s.learner == lr])) for lr in LEARNERS
                },
            }
        result["who"][w] = per
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "distances.json", json.dumps(result, indent=1) + "\n")
    text = markdown(result, who, tasks)
    write_text_atomic(out / "distances.md", text)
    print(text)
    return result


def markdown(result: dict[str, Any], who: Sequence[str], tasks: Sequence[int]) -> str:
    """Per statistic and Task: KS [band] for each participant side by side, with the medians."""
    head = ["statistic", "Task", "real median"]
    for w in who:
        head += [f"{WHO[w][2]}: median", "KS [95 % band]"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for st in STATISTICS:
        for t in tasks:
            if st == "turn" and t == 1:
                continue
            first = result["who"][who[0]][str(t)]["stats"][st]
            cells = [LABELS[st], str(t), f"{first['real_median']:.2f}"]
            for w in who:
                d = result["who"][w][str(t)]["stats"][st]
                cells += [
                    f"{d['sim_median']:.2f}",
                    f"{d['ks']:.2f} [{d['band'][0]:.2f}, {d['band'][1]:.2f}]",
                ]
            lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "| participant | Task | corrections / session (real) | by learner One / MOF / StROL "
        "(real) | rebounds | reflexes during a push |",
        "|---|---|---|---|---|---|",
    ]
    for w in who:
        for t in tasks:
            p = result["who"][w][str(t)]
            c = p["count_by_learner"]
            rc = p["real_count_by_learner"]
            d = p["stats"]["count"]
            lines.append(
                f"| {WHO[w][2]} | {t} | {d['sim_mean']:.2f} ({d['real_mean']:.2f}) | "
                + " / ".join(f"{c[lr]:.2f}" for lr in LEARNERS)
                + " ("
                + " / ".join(f"{rc[lr]:.2f}" for lr in LEARNERS)
                + f") | {p['rebounds']} of {p['corrections']} ({100 * p['rebound_share']:.1f} %) | "
                f"{p['reflexes']} |"
            )
    lines += [
        "",
        "| participant | Task | read scale: median read u_H / median intended (position, "
        "rotation) |",
        "|---|---|---|",
    ]
    for w in who:
        for t in tasks:
            sc = result["who"][w][str(t)]["read_scale"]
            cell = "no intended pushes recorded" if sc is None else f"{sc[0]:.3f}, {sc[1]:.3f}"
            lines.append(f"| {WHO[w][2]} | {t} | {cell} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("logs", help="a folder written by strol-bench import-study")
    p.add_argument("--users", type=int, default=12, help="simulated users per Task (12)")
    p.add_argument("--out", required=True)
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--who", default="v1,v2", help="v1 (v1's participant), v2 (fitted) or both")
    p.add_argument("--task", default="1,2,3")
    p.add_argument("--bootstrap", type=int, default=BOOTSTRAP)
    args = p.parse_args(argv)
    who = [w for w in args.who.split(",") if w]
    if any(w not in WHO for w in who) or args.users < 1 or args.jobs < 1:
        p.error(f"--who must name {sorted(WHO)}; --users and --jobs >= 1")
    tasks = [int(t) for t in args.task.split(",")]
    print(f"load {os.getloadavg()[0]:.1f}")
    run(args.logs, args.users, args.out, args.jobs, who, tasks, args.bootstrap)
    return 0


if __name__ == "__main__":
    sys.exit(main())
