"""What StROL-Study-v1's arm does when pushed: the figures docs/study.md quotes.

    .venv/bin/python lab/study/study_v1_physics.py [--seeds 10]

1. **Lag** while following a plan (no person): the cup's distance to its setpoint per step over
   the first 10 s of ``--seeds`` study seeds per Task; median, 95th percentile and maximum over
   the steps where the setpoint is within reach (no joint within 0.2 rad of a limit, no
   contact), and the share of steps outside reach; and the same over all steps.
2. **Hold drift**: after 2 s of following, ``pause(1)``: how far the cup moves in that second.
3. **Push angles**: 30 N along ±x, ±y, ±z for 1 s after 2 s of following: the angle between
   u_H's translation and the push, and its length; 2 N m about ±x, ±y, ±z (Tasks 2-3): the
   angle between u_H's rotation (world frame) and the torque.
4. **Reflex**: 200 N for 1 s: the step it trips, how long the brakes hold, the fastest joint
   relative to its limit; 60 N pushes in 14 directions: reflexes (should be none).
"""

from __future__ import annotations

import argparse
import math
import os
import warnings

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.envs.study.controller import VELOCITY_LIMIT
from strol_gym.envs.study.env import StudyEnvV1
from strol_gym.envs.study.geometry import rotation_error
from strol_gym.tasks.study import rpy_to_mat

SEED = 20000


def make(task: int) -> StudyEnvV1:
    env = gym.make("StROL-Study-v1", task=task, person=None).unwrapped
    assert isinstance(env, StudyEnvV1)
    return env


def run(env: StudyEnvV1, n: int) -> list[dict]:
    zero = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
    return [env.step(zero)[4] for _ in range(n)]


def reachable(env: StudyEnvV1) -> bool:
    """No joint within 0.2 rad of a limit (the stretched elbow's is the one that binds) and
    no contact."""
    q = env.data.qpos[:7]
    lo, hi = env.model.jnt_range[:7].T
    return bool(np.min(np.minimum(q - lo, hi - q)) > 0.2 and env.data.ncon == 0)


def lag(task: int, seeds: int) -> str:
    inside, everywhere, outside = [], [], 0
    for s in range(SEED, SEED + seeds):
        env = make(task)
        env.reset(seed=s)
        zero = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
        for _ in range(200):
            info = env.step(zero)[4]
            everywhere.append(info["lag"])
            if reachable(env):
                inside.append(info["lag"])
            else:
                outside += 1
    v = np.array(inside) * 1000
    a = np.array(everywhere) * 1000
    share = outside / (outside + len(v))
    return (
        f"lag (mm, reachable setpoints): median {np.median(v):.1f}, p95 "
        f"{np.percentile(v, 95):.1f}, max {v.max():.1f}; {share:.0%} of steps outside reach; "
        f"all steps: median {np.median(a):.1f}, p95 {np.percentile(a, 95):.1f}, max {a.max():.1f}"
    )


def hold(task: int, seeds: int) -> str:
    drift, turn, free = [], [], 0
    for s in range(SEED, SEED + seeds):
        env = make(task)
        env.reset(seed=s)
        run(env, 40)
        env.pause(1.0)
        x0 = env.data.site_xpos[env._site].copy()
        r0 = env.data.site_xmat[env._site].reshape(3, 3).copy()
        run(env, 20)
        drift.append(np.linalg.norm(env.data.site_xpos[env._site] - x0) * 1000)
        free += reachable(env)
        r1 = env.data.site_xmat[env._site].reshape(3, 3)
        turn.append(np.linalg.norm(rotation_error(r1, r0)))
    ok = sum(d < 2.0 and r < 0.01 for d, r in zip(drift, turn, strict=True))
    return (
        f"hold drift over {seeds} seeds: median {np.median(drift):.2f} mm, max {max(drift):.2f} "
        f"mm; rotation median {np.median(turn):.4f} rad, max {max(turn):.4f} rad; "
        f"< 2 mm and < 0.01 rad in {ok}/{seeds}; {free}/{seeds} within reach"
    )


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b) + 1e-12))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def _name(axis: int, sign: float) -> str:
    return ("+" if sign > 0 else "-") + "xyz"[axis]


def _push(task: int, seed: int, force, torque) -> dict:
    env = make(task)
    env.reset(seed=seed)
    run(env, 40)
    env.apply_wrench(force, torque, duration=1.0)
    return next(i for i in run(env, 30) if i["is_correction"])


def pushes(task: int, seed: int) -> str:
    lines = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            f = np.zeros(3)
            f[axis] = 30.0 * sign
            u = _push(task, seed, f, (0.0, 0.0, 0.0))["u_h"][:3]
            lines.append(
                f"{_name(axis, sign)} {_angle(u, f):.1f}° {100 * np.linalg.norm(u):.1f} cm"
            )
    out = "30 N pushes (angle, length): " + ", ".join(lines)
    if task == 1:
        return out
    lines = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            tq = np.zeros(3)
            tq[axis] = 2.0 * sign
            info = _push(task, seed, (0.0, 0.0, 0.0), tq)
            st, u = info["correction_state"], info["u_h"]
            rot = rotation_error(rpy_to_mat(st[3:] + u[3:]), rpy_to_mat(st[3:]))
            lines.append(
                f"{_name(axis, sign)} {_angle(rot, tq):.1f}° {np.linalg.norm(rot):.3f} rad"
            )
    return out + "\n  2 N m torques (angle, rotation): " + ", ".join(lines)


def reflex(task: int, seed: int) -> str:
    env = make(task)
    env.reset(seed=seed)
    run(env, 20)
    env.apply_wrench((0.0, -200.0, 0.0), duration=1.0)
    zero = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
    trip, braked, fastest, corrections = None, 0, 0.0, 0
    for k in range(60):
        info = env.step(zero)[4]
        fastest = max(fastest, float(np.max(np.abs(env.data.qvel[:7]) / VELOCITY_LIMIT)))
        trip = k if info["reflex"] and trip is None else trip
        braked += info["braked"]
        corrections += info["is_correction"]
    trips = 0
    rng = np.random.default_rng(0)
    dirs = [*np.eye(3), *-np.eye(3), *(v / np.linalg.norm(v) for v in rng.normal(size=(8, 3)))]
    for d in dirs:
        env = make(task)
        env.reset(seed=seed)
        run(env, 20)
        env.apply_wrench(60.0 * d, duration=1.0)
        trips += sum(i["reflex"] for i in run(env, 30))
    return (
        f"200 N shove: reflex on step {trip}, braked {braked * 0.05:.2f} s, fastest joint "
        f"{fastest:.2f} of its limit, corrections from it {corrections}; 60 N pushes in "
        f"{len(dirs)} directions: {trips} reflexes"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=10)
    args = p.parse_args()
    warnings.simplefilter("ignore", DeprecationWarning)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    for task in (1, 2, 3):
        print(f"Task {task}")
        print("  " + lag(task, args.seeds))
        print("  " + hold(task, args.seeds))
        print("  " + pushes(task, SEED + 1))
        print("  " + reflex(task, SEED + 1))
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
