"""Speed of StROL-Highway-v0 (env steps/s, rendering off), human controller included.

    .venv/bin/python benchmarks/speed/highway_env.py [--steps 5000] [--repeats 3] [--compare]
    .venv/bin/python benchmarks/speed/highway_env.py --learning 50
        [--sigma S --bias B --prior P]

Rows: the default env (eq. M6 "nominal" human with 512 candidates, 10-step episodes, resets
included), the human correcting on every step (no resets), the "boltzmann" and "driver" humans,
and the batched default robot policy (calls/s and states/s for a block of 100). Each figure is
the best of ``--repeats`` timed runs with random actions. ``--compare`` also times highway-env's
own ``highway-fast-v0`` for reference. Target: ≥ 1,000 steps/s.

``--learning N`` instead runs N episodes (seeds 0..N−1) of the env per learner through
``OnlineLearningWrapper``, the robot driven by ``task.robot_policy`` with that learner's θ̂, and
prints each learner's mean final error ‖θ* − θ̂‖, mean 1 − cos(θ*, θ̂), collisions, and the
paired StROL − Gradient difference.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import strol_gym
from strol_gym.benchmarks.speed.timing import env_steps_per_second
from strol_gym.envs.highway.env import HighwayEnv


def best_rate(fn: Callable[[], object], n: int, repeats: int) -> float:
    best = 0.0
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            fn()
        best = max(best, n / (time.perf_counter() - start))
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--compare", action="store_true", help="also time highway-fast-v0")
    parser.add_argument("--learning", type=int, default=0, help="episodes per learner")
    parser.add_argument("--sigma", type=float, default=0.0)
    parser.add_argument("--bias", type=float, default=0.0)
    parser.add_argument("--prior", default="bimodal")
    args = parser.parse_args()
    if args.learning:
        learning(args.learning, args.sigma, args.bias, args.prior)
        return
    long = 10**9
    rows: dict[str, gym.Env] = {
        "default (nominal human, 10-step episodes)": gym.make("StROL-Highway-v0"),
        "nominal human correcting every step": HighwayEnv(
            n_corrections=long, max_episode_steps=long
        ),
        "boltzmann human, 10-step episodes": gym.make("StROL-Highway-v0", person="boltzmann"),
        "driver human, 10-step episodes": gym.make("StROL-Highway-v0", person="driver"),
        "sigma=0.5, bias=0.5 (nominal)": gym.make(
            "StROL-Highway-v0", person={"sigma": 0.5, "bias": 0.5}
        ),
    }
    for name, env in rows.items():
        print(f"{name:45s} {env_steps_per_second(env, args.steps, args.repeats):8.0f} steps/s")
        env.close()

    task = strol_gym.HighwayTask()
    rng = np.random.default_rng(1)
    x, th = task.sample_start(rng, 100), task.prior.sample(rng, 100)
    rate = best_rate(lambda: task.robot_policy(x, th), 10, args.repeats)
    print(
        f"{'robot_policy, block of 100 states':45s} {rate:8.1f} calls/s ({100 * rate:.0f} states/s)"
    )

    if args.compare:
        import highway_env  # noqa: F401

        env = gym.make("highway-fast-v0")
        env.reset(seed=0)
        n = min(args.steps, 300)
        start = time.perf_counter()
        for _ in range(n):
            *_, term, trunc, _ = env.step(env.action_space.sample())
            if term or trunc:
                env.reset()
        rate = n / (time.perf_counter() - start)
        print(f"{'highway-env highway-fast-v0 (reference)':45s} {rate:8.0f} steps/s")


def learning(episodes: int, sigma: float, bias: float, prior: str) -> None:
    from strol_gym.wrappers.online_learning import OnlineLearningWrapper, learning_env

    print(f"{episodes} episodes, sigma={sigma}, bias={bias}, prior={prior}, default robot policy")
    errors = {}
    for name in ("gradient", "one", "mof", "e2e", "strol"):
        env = gym.make("StROL-Highway-v0", person={"sigma": sigma, "bias": bias}, prior=prior)
        task = learning_env(env).task
        wrapped = OnlineLearningWrapper(env, strol_gym.make_learner(name, task=task))
        err, cos, crashes = [], [], 0
        for seed in range(episodes):
            obs, info = wrapped.reset(seed=seed)
            term = trunc = False
            while not (term or trunc):
                u = task.robot_policy(obs["state"], wrapped.learner.theta)[0]
                action = np.clip(u / task.robot_action_bound, -1, 1).astype(np.float32)
                obs, _, term, trunc, info = wrapped.step(action)
            err.append(info["error"])
            cos.append(info["cos_error"])
            crashes += bool(term)
        env.close()
        errors[name] = np.array(err)
        print(
            f"{name:9s} error {np.mean(err):.3f} ± {np.std(err):.3f}   "
            f"1 − cos {np.mean(cos):.3f}   collisions {crashes}/{episodes}"
        )
    diff = errors["strol"] - errors["gradient"]
    print(
        f"StROL − Gradient {diff.mean():+.3f} (StROL lower in {np.mean(diff < 0):.0%} "
        "of the paired episodes)"
    )


if __name__ == "__main__":
    main()
