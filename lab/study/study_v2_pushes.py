"""Held-out pushes on StROL-Study-v2 (or v1): how well u_H reads the push.

    .venv/bin/python lab/study/study_v2_pushes.py [--pushes 200] [--seed 0] [--version v2]

Each push: a random study seed (episode), a random time 2-8 s into the episode, a force of
20-60 N in a random direction and (Tasks 2-3) a torque of 1-3 N m about a random axis, for
1 s, through the public push API (``apply_wrench``; ``person=None``). Prints per Task the
angle between u_H's translation and the force, between u_H's rotation (the world-frame turn
R(x + u) R(x)⁻¹) and the torque's axis, and the 30 N, 1 s displacement; the pushes the
reflex stopped (no correction), and the same angles without the pushes that pressed the cup
into an object (``info["contact"]``) or drove a joint to its limit (physics, not u_H's
reading), and the misses counted by what the push met (an object, a joint's limit, the
wrist's singularity, nothing). The draws come from ``--seed`` (not a seed any test uses).
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import gymnasium as gym
import numpy as np

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym import checks
from strol_gym.envs.study.geometry import rotation_error
from strol_gym.tasks.study import rpy_to_mat


def angle(a: np.ndarray, b: np.ndarray) -> float:
    """Degrees between two vectors (180 if either is zero)."""
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na < 1e-12 or nb < 1e-12:
        return 180.0
    return math.degrees(math.acos(max(-1.0, min(1.0, float(a @ b) / float(na * nb)))))


def unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def push_case(version: str, task: int, rng: np.random.Generator) -> dict:
    """One held-out push: its draws and what u_H made of it."""
    seed = int(rng.integers(20000, 30000))
    start = float(rng.uniform(2.0, 8.0))
    force = unit(rng) * rng.uniform(20.0, 60.0)
    torque = unit(rng) * rng.uniform(1.0, 3.0) if task > 1 else np.zeros(3)
    return run_push(version, task, seed, start, force, torque)


def run_push(
    version: str, task: int, seed: int, start: float, force: np.ndarray, torque: np.ndarray
) -> dict:
    env: Any = gym.make(f"StROL-Study-{version}", task=task, person=None).unwrapped  # StudyEnv
    env.reset(seed=seed)
    zero = np.zeros(checks.space_shape("action_space", env.action_space), np.float32)
    for _ in range(round(start / 0.05)):
        env.step(zero)
    env.apply_wrench(force, torque, duration=1.0)
    out = {"seed": seed, "start": start, "force": force, "torque": torque, "ok": False}
    lo, hi = env.model.jnt_range[:7].T
    kinds: set[str] = set()
    wrist = math.pi / 2
    for _ in range(40):
        _, _, _, truncated, info = env.step(zero)
        if info.get("reflex"):
            out["reflex"] = True
        q = env.data.qpos[:7]
        room = np.minimum(q - lo, hi - q)
        if info.get("contact", False):
            kinds.add("contact")
        if np.any(room < 0.01):
            kinds.add(f"joint {int(np.argmin(room)) + 1} at its limit")
        wrist = min(wrist, abs(float(q[5]) - math.pi / 2))  # joints 5, 7 parallel at π/2
        if info["is_correction"]:
            u, x = info["u_h"], info["correction_state"]
            out.update(ok=True, u_h=u, length=float(np.linalg.norm(u[:3])))
            out["trans"] = angle(u[:3], force)
            if len(u) > 3:
                turn = rotation_error(rpy_to_mat(x[3:] + u[3:]), rpy_to_mat(x[3:]))
                out["rot"] = angle(turn, torque)
                out["turn"] = float(np.linalg.norm(turn))
            break
        if truncated:
            break
    out["blocked"] = bool(kinds)
    out["kind"] = ", ".join(sorted(kinds)) or (
        f"wrist within {math.degrees(WRIST_NEAR):.0f}° of singular"
        if wrist < WRIST_NEAR
        else "free"
    )
    env.close()
    return out


WRIST_NEAR = math.radians(15.0)
"""A push whose joint 6 came this close to π/2 (joints 5's and 7's axes parallel: the wrist's
singularity) is labelled so among the misses: there a small turn spins both joints."""


def misses_by_kind(cases: list[dict]) -> str:
    """How many read pushes missed a target (translation beyond 15°, rotation beyond 30°), by
    what the push met: an object, a joint's limit, the wrist's singularity, or nothing."""
    counts: dict[str, int] = {}
    for c in cases:
        if c["trans"] > 15.0 or c.get("rot", 0.0) > 30.0:
            counts[c["kind"]] = counts.get(c["kind"], 0) + 1
    return ", ".join(f"{k} {n}" for k, n in sorted(counts.items())) or "none"


def summary(name: str, values: list[float], bound: float) -> str:
    v = np.array(values)
    within = float(np.mean(v <= bound)) if len(v) else float("nan")
    return (
        f"{name}: n={len(v)} median {np.median(v):.1f}° p95 {np.percentile(v, 95):.1f}° "
        f"max {v.max():.1f}°, within {bound:g}°: {within:.1%}, over 90°: {int(np.sum(v > 90))}"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pushes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--version", default="v2", choices=("v1", "v2"))
    parser.add_argument("--tasks", default="1,2,3")
    args = parser.parse_args(argv)
    for task in (int(t) for t in args.tasks.split(",")):
        rng = np.random.default_rng([args.seed, task])
        cases = [push_case(args.version, task, rng) for _ in range(args.pushes)]
        done = [c for c in cases if c["ok"]]
        print(f"Task {task} ({args.version}): {len(done)}/{len(cases)} pushes read as corrections")
        free = [c for c in done if not c["blocked"]]
        for name, group in (("", done), ("no contact or joint limit: ", free)):
            print(f"  {name}" + summary("translation vs force", [c["trans"] for c in group], 15.0))
            if task > 1:
                print(
                    f"  {name}"
                    + summary("rotation vs torque axis", [c["rot"] for c in group], 30.0)
                )
        print(f"  misses by what the push met: {misses_by_kind(done)}")
        lengths = np.array([c["length"] for c in done])
        print(f"  |u_H| translation: median {np.median(lengths) * 100:.1f} cm")
        sides = [run_push(args.version, task, 20001, 3.0, 30.0 * d, np.zeros(3)) for d in np.eye(3)]
        print(
            "  30 N, 1 s along x, y, z (seed 20001, t = 3 s): "
            + ", ".join(f"{c['length'] * 100:.1f} cm ({c['trans']:.1f}°)" for c in sides)
        )


if __name__ == "__main__":
    main()
