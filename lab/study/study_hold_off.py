"""StROL-Study-v2's hold-off: how much u_H depends on it, and how the participant's pushes split.

    .venv/bin/python lab/study/study_hold_off.py [--pushes 40] [--seed 7] [--hold-off 0.3]
        [--episodes 0]

Pushes: a random study seed (40000-59999, no test's), Task and 30 N direction; the arm either
settled (1 s along its plan, then a 1 s pause) or moving along its plan (0.5-5 s in); a 30 N
push for 0.8 s through ``apply_wrench`` (``person=None``), once with ``hold_off=0`` and once
with ``--hold-off``. Prints the relative change of u_H's translation, |u(h) − u(0)| / |u(0)|:
median, 90th percentile, max, share within 10 %. Episodes: the default participant over 30 s
with StROL learning (Tasks 1-3, seeds 71001-...), at ``hold_off`` 0 and ``--hold-off``:
corrections, reflexes, and the gaps between the stretches the force spends above 15 N.
"""

from __future__ import annotations

import argparse
import warnings
from typing import Any

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.tasks.study import CONTROL_DT


def _run(env: Any, n: int) -> list[dict]:
    zero = np.zeros(checks.space_shape("action_space", env.action_space), np.float32)
    return [env.step(zero)[4] for _ in range(n)]


def push_u_h(task: int, seed: int, moving: int, force: np.ndarray, hold_off: float) -> Any:
    """u_H's translation for the push (None if the speed reflex stopped it)."""
    env: Any = gym.make("StROL-Study-v2", task=task, person=None, hold_off=hold_off).unwrapped
    env.reset(seed=seed)
    if moving:
        _run(env, moving)
    else:
        _run(env, 20)
        env.pause(1.0)
        _run(env, 20)
    env.apply_wrench(force, duration=0.8)
    ends = [i for i in _run(env, 40) if i["is_correction"]]
    return ends[0]["u_h"][:3] if ends else None


def pushes(n: int, seed: int, hold_off: float) -> None:
    rng = np.random.default_rng(seed)
    change, lost = [], 0
    for _ in range(n):
        study_seed, task = int(rng.integers(40000, 60000)), int(rng.integers(1, 4))
        moving = int(rng.integers(0, 2)) * int(rng.integers(10, 100))
        d = rng.normal(size=3)
        force = 30.0 * d / np.linalg.norm(d)
        u0 = push_u_h(task, study_seed, moving, force, 0.0)
        u1 = push_u_h(task, study_seed, moving, force, hold_off)
        if u0 is None or u1 is None:
            lost += 1
            continue
        change.append(float(np.linalg.norm(u1 - u0) / np.linalg.norm(u0)))
    c = np.array(change)
    print(
        f"{len(c)} pushes ({lost} stopped by the reflex), hold-off {hold_off} s vs none: "
        f"|Δu_H|/|u_H| median {np.median(c):.3f}, p90 {np.quantile(c, 0.9):.3f}, "
        f"max {c.max():.3f}; within 10 %: {np.mean(c <= 0.10):.1%}"
    )


def episodes(n: int, hold_off: float) -> None:
    from strol_gym.wrappers import OnlineLearningWrapper

    for task in (1, 2, 3):
        for seed in range(71001, 71001 + n):
            for h in (0.0, hold_off):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    base = gym.make("StROL-Study-v2", task=task, hold_off=h, max_episode_steps=600)
                env: Any = OnlineLearningWrapper(base, "strol")
                env.reset(seed=seed)
                above, ends, reflexes, done = [], 0, 0, False
                zero = np.zeros(checks.space_shape("action_space", env.action_space), np.float32)
                while not done:
                    _, _, term, trunc, info = env.step(zero)
                    done = term or trunc
                    w = info["wrench"]
                    above.append(np.linalg.norm(w[:3]) + np.linalg.norm(w[3:]) / 0.1 > 15.0)
                    reflexes += bool(info["reflex"])
                    ends += bool(info["is_correction"])
                edges = np.diff(np.array(above, dtype=int))
                ups, downs = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
                gaps = [CONTROL_DT * (ups[ups > d][0] - d) for d in downs if (ups > d).any()]
                print(
                    f"Task {task} seed {seed} hold-off {h}: {ends} corrections, {reflexes} "
                    f"reflexes, {len(ups)} stretches above 15 N, shortest gaps "
                    f"{sorted(round(g, 2) for g in gaps)[:3]} s"
                )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--pushes", type=int, default=40)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--hold-off", type=float, default=0.3)
    p.add_argument("--episodes", type=int, default=0, help="participant episodes per Task")
    a = p.parse_args()
    if a.pushes:
        pushes(a.pushes, a.seed, a.hold_off)
    if a.episodes:
        episodes(a.episodes, a.hold_off)


if __name__ == "__main__":
    main()
