"""How far One moves θ̂ when it steps as the authors' learner did, against v2's one step per push.

v2's learners make one update per push: α = 2 on the whole push u_H. The authors' learner made
one update per consecutive pair of the poses their loop logged (a pose at each new force maximum,
``metrics.new_maxima``): α = 1 on u = 3 (x_{k+1} − x_k) (``authors_rules``). Both rules on the
same pushes, with the Task's own φ:

- ``sim``: simulated sessions on StROL-Study-v2 (the shipped population), v2's One in the loop;
  per correction the cup's poses at the control steps where ‖F‖ rises above its running maximum,
  and the authors' per-pair One on them, offline (the pushes are those v2's One met).
- ``real LOGS``: the twelve people's corrections, imported one line per pair
  (``strol-bench import-study DATA --out LOGS --authors-updates``): the per-pair One, and v2's
  rule on the whole logged push (x at its first pose, u_H = Σ Δ).

One's update does not depend on θ̂, so a session's net move is the norm of its summed steps.

    python -m lab.study.authors_stepping sim --users 12 --seed 20000 [--ramp 1.0]
    python -m lab.study.authors_stepping real LOGS
"""

from __future__ import annotations

import argparse
import itertools
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.benchmarks.sessions.authors_rules import AUTHORS_ALPHA, AUTHORS_GAIN
from strol_gym.envs.study.geometry import angle_delta
from strol_gym.envs.study.metrics import new_maxima
from strol_gym.learners.registry import make_learner
from strol_gym.tasks.study import STUDY_TASKS_V2
from strol_gym.wrappers import OnlineLearningWrapper

Row = dict[str, Any]


def authors_one(task: Any) -> Any:
    """One on ``task``'s φ with the authors' α."""
    return make_learner("one", task=type(task)(alpha=AUTHORS_ALPHA))


def pair_steps(learner: Any, poses: np.ndarray) -> np.ndarray:
    """θ̂ after − before of ``learner`` stepping once per consecutive pair of ``poses``."""
    before = np.array(learner.theta, dtype=np.float64)
    for a, b in itertools.pairwise(poses):
        u = AUTHORS_GAIN * angle_delta(b, a)
        learner.update(a, u, np.zeros_like(u))
    return np.asarray(learner.theta, dtype=np.float64) - before


def sim_session(number: int, seed: int, ramp: float | None = None) -> Row:
    """One simulated session of Task ``number``: per correction v2's step, the authors' step,
    the logged poses, |u_H| and the span of the logged poses (positions, m). ``ramp``: the
    people's force rises (and falls) over that many s instead of their own."""
    kwargs: dict[str, Any] = {"task": number}
    if ramp is not None:
        kwargs["person"] = {"name": "fitted", "kwargs": {"ramp": ramp}}
    env = OnlineLearningWrapper(gym.make("StROL-Study-v2", **kwargs), "one")
    _, info = env.reset(seed=seed)
    theta0 = np.asarray(info["theta_hat0"], dtype=np.float64)
    authors = authors_one(env.task)
    authors.reset(np.zeros_like(theta0))
    poses: list[np.ndarray] = []
    forces: list[float] = []
    rows: list[Row] = []
    zero = np.zeros(np.shape(env.task.robot_action_bound), dtype=np.float32)
    done = False
    while not done:
        before = np.asarray(env.learner.theta, dtype=np.float64).copy()
        obs, _, term, trunc, info = env.step(zero)
        done = term or trunc
        if info["correction_active"]:
            poses.append(np.asarray(obs["state"], dtype=np.float64))
            forces.append(float(np.linalg.norm(info["wrench"][:3])))
        if info["is_correction"]:
            logged = np.array([poses[i] for i in new_maxima(forces)])
            logged = logged.reshape(-1, obs["state"].shape[0])
            step = pair_steps(authors, logged) if len(logged) >= 2 else np.zeros_like(theta0)
            rows.append(
                {
                    "v2": float(np.linalg.norm(info["theta_hat"] - before)),
                    "authors": float(np.linalg.norm(step)),
                    "poses": len(logged),
                    "u_h": float(np.linalg.norm(obs["correction"][:3])),
                    "span": float(np.linalg.norm(logged[-1, :3] - logged[0, :3]))
                    if len(logged)
                    else 0.0,
                }
            )
            poses, forces = [], []
    net_v2 = float(np.linalg.norm(np.asarray(env.learner.theta) - theta0))
    return {
        "task": number,
        "seed": seed,
        "corrections": rows,
        "net_v2": net_v2,
        "net_authors": float(np.linalg.norm(authors.theta)),
    }


def real_sessions(folder: Path) -> list[Row]:
    """The imported per-pair logs: per physical correction the authors' and v2's One steps."""
    out = []
    for path in sorted(folder.glob("*.jsonl")):
        lines = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
        header = lines[0]
        number = int(header["extra"]["study_task"])
        pushes: dict[int, list[Row]] = defaultdict(list)
        for r in lines:
            if r["type"] == "correction":
                pushes[int(r["physical_correction"])].append(r)
        task = STUDY_TASKS_V2[number]()
        authors, v2 = authors_one(task), make_learner("one", task=task)
        authors.reset(np.zeros(task.dim))
        v2.reset(np.zeros(task.dim))
        rows = []
        for pairs in pushes.values():
            x = np.array([p["x"] for p in pairs], dtype=np.float64)
            u = np.array([p["u_h"] for p in pairs], dtype=np.float64) / AUTHORS_GAIN
            logged = np.vstack([x, x[-1] + u[-1]])
            step = pair_steps(authors, logged)
            before = np.asarray(v2.theta, dtype=np.float64).copy()
            whole = angle_delta(x[0] + u.sum(axis=0), x[0])
            v2.update(x[0], whole, np.zeros_like(whole))
            rows.append(
                {
                    "v2": float(np.linalg.norm(np.asarray(v2.theta) - before)),
                    "authors": float(np.linalg.norm(step)),
                    "poses": len(logged),
                    "u_h": float(np.linalg.norm(whole[:3])),
                    "span": float(np.linalg.norm(whole[:3])),
                }
            )
        out.append(
            {
                "task": number,
                "learner": header["extra"]["authors_folder"],
                "corrections": rows,
                "net_v2": float(np.linalg.norm(v2.theta)),
                "net_authors": float(np.linalg.norm(authors.theta)),
            }
        )
    return out


def summary(sessions: list[Row], label: str) -> str:
    """Medians over corrections and sessions."""
    rows = [c for s in sessions for c in s["corrections"]]

    def med(key: str, over: list[Row]) -> float:
        return float(np.median([r[key] for r in over])) if over else float("nan")

    return (
        f"{label}: {len(sessions)} sessions, {len(rows)} corrections "
        f"({len(rows) / max(len(sessions), 1):.2f} per session); per correction, median: "
        f"|Δθ̂| v2 {med('v2', rows):.3f}, authors {med('authors', rows):.3f}; logged poses "
        f"{med('poses', rows):.0f}, their span {med('span', rows):.3f} m, "
        f"|u_H| {med('u_h', rows):.3f} m; "
        f"net |Δθ̂| per session, median: v2 {med('net_v2', sessions):.2f}, "
        f"authors {med('net_authors', sessions):.2f}"
    )


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="what", required=True)
    s = sub.add_parser("sim", help="simulated sessions on StROL-Study-v2")
    s.add_argument("--users", type=int, default=12)
    s.add_argument("--seed", type=int, default=20000)
    s.add_argument(
        "--ramp", type=float, default=None, help="the push's rise (s; default: the population's)"
    )
    r = sub.add_parser("real", help="the people's corrections, imported with --authors-updates")
    r.add_argument("logs", type=Path)
    args = p.parse_args(argv)
    if args.what == "sim":
        if not 1 <= args.users <= 1000:
            p.error(f"--users must be in [1, 1000], got {args.users}")
        if args.ramp is not None and not 0.05 <= args.ramp <= 5.0:
            p.error(f"--ramp must be in [0.05, 5] s, got {args.ramp}")
        sessions = []
        for number in (1, 2, 3):
            done = [sim_session(number, args.seed + k, args.ramp) for k in range(args.users)]
            print(summary(done, f"Task {number}"), flush=True)
            sessions += done
        print(summary(sessions, "all Tasks"))
        return
    sessions = real_sessions(args.logs)
    for who in ("b1", "b2", "ours"):
        print(summary([x for x in sessions if x["learner"] == who], f"real {who}"))


if __name__ == "__main__":
    main()
