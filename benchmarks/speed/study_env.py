"""Speed of StROL-Study-v0/v1/v2: physics overhead and a full simulated-user episode with StROL.

    .venv/bin/python benchmarks/speed/study_env.py [--task 1] [--repeats 3] [--version v1]
    .venv/bin/python benchmarks/speed/study_env.py --episode [--task 1] [--repeats 1]
    .venv/bin/python benchmarks/speed/study_env.py --episode --task all --repeats 2 --versions v2

``--episode``: v2's figure, the physics over whole 60 s episodes with the default person,
v1 and v2 alternately in one process (``episode_physics``); beside the ratio against bare
``mj_step`` from the episode's last state, ``ratio_own_states``: against bare ``mj_step`` from
every state the episode visited (a control step's ten physics steps from each, its torques
held), since one state's physics cost can differ from the episode's by 1.7x; and
``ratio_paired``: the same, each bare control step timed just before the env's own from the
same state, so that both meet the same moment's load on a shared machine. ``--task all``
runs Tasks 1-3 and ends with v2's ``ratio_paired`` per Task (the lowest of its seeds), the
study's physics target (≥ 0.7 on every Task).

1. **Physics overhead**: physics steps per second of the env (controller, wrench bookkeeping,
   feature computation; no user, no planning, no rendering; 200 env steps = 2,000 physics
   steps, before the plan ends so nothing replans) over those of bare ``mujoco.mj_step`` on the
   same compiled model from the same state (the env's after 1 s of motion, its last torques
   held), timed alternately in one process; best of ``--repeats`` each. Target ≥ 0.7.
2. **Real-time factor**: one 60 s episode (1,200 steps) with the simulated user (eq. M6,
   σ = 0.25; on v1 the default participant, who judges what it sees) and StROL through
   ``OnlineLearningWrapper``, replanning included: simulated
   seconds per wall-clock second. Target ≥ 30.

One core (BLAS and torch threads pinned to 1); the physics figures (1 and ``--episode``) time
this process's CPU time, the real-time factor wall time. Seeds from the study range (20000-).
"""

from __future__ import annotations

import os
from typing import Any

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: before numpy loads its BLAS

import argparse  # noqa: E402
import time  # noqa: E402

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import strol_gym  # noqa: E402, F401  (registers the envs)
from strol_gym import checks  # noqa: E402
from strol_gym.envs.study import env as study_env  # noqa: E402
from strol_gym.envs.study.versions import V0, V1, V2, VERSIONS  # noqa: E402

SEED = 20100
_clock = time.process_time
"""The physics figures' clock: this process's CPU time (one thread), so that other processes
on a shared machine do not count as the env's or the bare physics' cost."""


def _person(version: str) -> dict[str, Any]:
    """The simulated person the timed episodes use: the version's default, with σ = 0.25 where
    it takes σ (v0's oracle, v1's observer; v2's fitted person's noise is fitted)."""
    takes_sigma = "fitted" not in VERSIONS[version].participants
    return {"person": {"sigma": 0.25}} if takes_sigma else {}


def physics_ratio(
    task: int, repeats: int, env_steps: int = 200, version: str = V0.name
) -> tuple[float, float, float]:
    """(env physics steps/s, bare mj_step steps/s, ratio)."""
    env = _ENVS[version](task=task, person=None)
    zero = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
    n_sub = env._n_sub
    bare_data = mujoco.MjData(env.model)
    best_env = best_bare = 0.0
    for r in range(repeats):
        env.reset(seed=SEED + r)
        for _ in range(20):  # under way: the bare run starts from a moving arm, as the env's
            env.step(zero)
        mujoco.mj_setState(
            env.model,
            bare_data,
            _state(env),
            mujoco.mjtState.mjSTATE_INTEGRATION,
        )
        start = _clock()
        for _ in range(env_steps):
            env.step(zero)
        best_env = max(best_env, env_steps * n_sub / (_clock() - start))
        start = _clock()
        for _ in range(env_steps):
            mujoco.mj_step(env.model, bare_data, nstep=n_sub)
        best_bare = max(best_bare, env_steps * n_sub / (_clock() - start))
    env.close()
    return best_env, best_bare, best_env / best_bare


_ENVS = {v.name: getattr(study_env, v.env_class) for v in VERSIONS.values()}


def episode_physics(task: int, version: str, seed: int = SEED) -> tuple[float, float, float, dict]:
    """Physics over a whole 60 s episode with the version's default simulated person (pushes,
    reflexes and, on v2, the counterfactual reruns included) and StROL: (env physics steps/s
    counting only the time inside the env's physics, bare ``mj_step`` steps/s on the same model
    from the episode's last state, ratio, summary). The planner and the person's own Python are
    not physics and not counted."""
    import torch

    from strol_gym.wrappers import OnlineLearningWrapper

    torch.set_num_threads(1)
    env = OnlineLearningWrapper(
        gym.make(VERSIONS[version].env_id, task=task, **_person(version)), "strol"
    )
    inner: Any = env.unwrapped  # the study env itself: its physics step is timed in place
    spent = [0.0, 0.0]  # the env's physics; bare mj_step's, paired with it step by step
    simulate = inner._simulate
    visited: list[np.ndarray] = []  # the state at each control step (counterfactuals aside)
    paired = mujoco.MjData(inner.model)
    spec = mujoco.mjtState.mjSTATE_INTEGRATION

    def timed(v_sp: Any) -> None:
        if not inner._rerun:
            visited.append(_state(inner))
            # the same control step of bare physics from this state, timed just before the
            # env's: both meet the same moment's load
            mujoco.mj_setState(inner.model, paired, visited[-1], spec)
            t0 = _clock()
            mujoco.mj_step(inner.model, paired, nstep=inner._n_sub)
            spent[1] += _clock() - t0
        t0 = _clock()
        simulate(v_sp)
        spent[0] += _clock() - t0

    inner._simulate = timed
    zero = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
    env.reset(seed=seed)
    truncated = False
    while not truncated:
        _, _, _, truncated, info = env.step(zero)
    steps = round(info["time"] / inner.model.opt.timestep)
    bare = mujoco.MjData(inner.model)
    mujoco.mj_setState(inner.model, bare, _state(inner), mujoco.mjtState.mjSTATE_INTEGRATION)
    t0 = _clock()
    for _ in range(steps // inner._n_sub):
        mujoco.mj_step(inner.model, bare, nstep=inner._n_sub)
    bare_rate = steps / (_clock() - t0)
    env_rate = steps / spent[0]
    own = 0.0  # bare mj_step from each state the episode visited, its torques held
    for state in visited:
        mujoco.mj_setState(inner.model, bare, state, mujoco.mjtState.mjSTATE_INTEGRATION)
        t0 = _clock()
        mujoco.mj_step(inner.model, bare, nstep=inner._n_sub)
        own += _clock() - t0
    own_rate = len(visited) * inner._n_sub / own
    paired_rate = len(visited) * inner._n_sub / spent[1]
    summary = {
        "bare_own_states": round(own_rate),
        "ratio_own_states": round(env_rate / own_rate, 2),
        "ratio_paired": round(env_rate / paired_rate, 2),
        "corrections": info["corrections"],
        "correction_time_s": round(info["correction_time"], 2),
        "reflexes": info.get("reflexes"),
    }
    env.close()
    return env_rate, bare_rate, env_rate / bare_rate, summary


def _state(env: study_env.StudyEnv) -> np.ndarray:
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    out = np.empty(mujoco.mj_stateSize(env.model, spec))
    mujoco.mj_getState(env.model, env.data, out, spec)
    return out


def realtime_factor(task: int, repeats: int, version: str = V0.name) -> tuple[float, dict]:
    """(best simulated s / wall s over ``repeats`` episodes, the last episode's summary)."""
    import torch

    from strol_gym.wrappers import OnlineLearningWrapper

    torch.set_num_threads(1)
    env = OnlineLearningWrapper(
        gym.make(VERSIONS[version].env_id, task=task, **_person(version)), "strol"
    )
    zero = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
    best, summary = 0.0, {}
    for r in range(repeats):
        env.reset(seed=SEED + r)
        start = time.perf_counter()
        truncated = False
        while not truncated:
            _, _, _, truncated, info = env.step(zero)
        wall = time.perf_counter() - start
        best = max(best, info["time"] / wall)
        summary = {
            "sim_s": round(info["time"], 2),
            "wall_s": round(wall, 2),
            "corrections": info["corrections"],
            "correction_time_s": round(info["correction_time"], 2),
            "error": round(info["error"], 3),
            "regret": round(info["regret"], 3),
        }
    env.close()
    return best, summary


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", default="1", choices=("1", "2", "3", "all"))
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--version", default=V1.name, choices=tuple(VERSIONS), help="the env version")
    p.add_argument(
        "--versions",
        default=f"{V1.name},{V2.name}",
        help="--episode: the versions timed, comma-separated (default v1,v2)",
    )
    p.add_argument(
        "--episode",
        action="store_true",
        help="the physics ratio over a whole 60 s episode with the default person, v1 and v2 "
        "alternately in this process (StROL-Study-v2's figure)",
    )
    args = p.parse_args()
    tasks = (1, 2, 3) if args.task == "all" else (int(args.task),)
    if args.episode:
        versions = [v.strip() for v in args.versions.split(",")]
        unknown = sorted(set(versions) - set(VERSIONS))
        if unknown:
            p.error(f"--versions: unknown {unknown}; choose from {sorted(VERSIONS)}")
        paired: dict[int, list[float]] = {}
        for task in tasks:
            print(f"task {task}; load average before: {os.getloadavg()[0]:.2f}")
            for r in range(args.repeats):
                for version in versions:
                    env_rate, bare_rate, ratio, summary = episode_physics(task, version, SEED + r)
                    print(
                        f"{version} seed {SEED + r}: physics {env_rate:,.0f} steps/s, bare "
                        f"mj_step {bare_rate:,.0f}/s, ratio {ratio:.2f} (target >= 0.70); "
                        f"{summary}"
                    )
                    if version == V2.name:
                        paired.setdefault(task, []).append(summary["ratio_paired"])
            print(f"load average after: {os.getloadavg()[0]:.2f}")
        for task, ratios in paired.items():
            print(
                f"v2 task {task}: ratio_paired {min(ratios):.2f} (lowest of seeds "
                f"{SEED}-{SEED + len(ratios) - 1}: {ratios}; target >= 0.70)"
            )
        return
    if len(tasks) > 1:
        p.error("--task all needs --episode")
    task = tasks[0]
    load = os.getloadavg()
    print(f"{VERSIONS[args.version].env_id} task {task}; load average before: {load[0]:.2f}")
    env_rate, bare_rate, ratio = physics_ratio(task, args.repeats, version=args.version)
    print(
        f"physics overhead: env {env_rate:,.0f} physics steps/s, bare mj_step "
        f"{bare_rate:,.0f}/s, ratio {ratio:.2f} (target >= 0.70)"
    )
    factor, summary = realtime_factor(task, args.repeats, args.version)
    print(
        f"60 s episode, simulated user + StROL: {factor:.1f}x real time (target >= 30); {summary}"
    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
