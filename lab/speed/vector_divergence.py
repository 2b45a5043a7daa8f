"""How often a sub-env of the native vector env departs from the single env (near-ties).

    .venv/bin/python -m lab.speed.vector_divergence [--seeds 1000] [--env both]

For each seed s in 0..seeds−1: one whole episode of the single env (``gymnasium.make``, reset
with seed s) and sub-env s of one vector env of ``seeds`` sub-envs (``gymnasium.make_vec``,
reset with the list of seeds), both under the same actions (drawn from s). An episode diverges
when any observation, reward, flag or info number differs by more than 1e-9. The vector env
computes each sub-env with the same operations, batched; where rounding differs (the batched
IK's kinematics agree with MuJoCo's to ~1e-15, not bit for bit) a threshold test on a near-tie
(an IK iteration's tolerance check, a joint limit, the IK's restart) can flip, and the episode
then differs. Prints, per setting, the count and rate of diverging episodes and the largest
difference seen in the others.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
from typing import Any  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import strol_gym  # noqa: E402, F401  (registers the envs)
from strol_gym import checks  # noqa: E402

TOL = 1e-9
ENV_IDS = {"robot": "StROL-Robot-v0", "highway": "StROL-Highway-v0"}
SETTINGS: dict[str, dict[str, Any]] = {
    "default human": {},
    "noisy-biased (σ = ε = 0.5)": {"person": {"sigma": 0.5, "bias": 0.5}},
    "no human (n_corrections=0)": {"n_corrections": 0},
}
INFO_KEYS = ("phi", "correction", "robot_action", "theta_star", "theta_hat")
EXTRA_KEYS = {"StROL-Robot-v0": ("target", "ik_error"), "StROL-Highway-v0": ()}


def _numbers(obs: dict, reward, term, trunc, info: dict, extra: tuple) -> np.ndarray:
    parts = [np.asarray(obs[k], dtype=np.float64).ravel() for k in sorted(obs)]
    parts += [np.asarray(info[k], dtype=np.float64).ravel() for k in (*INFO_KEYS, *extra)]
    flags = [reward, float(term), float(trunc), float(info["is_correction"])]
    return np.concatenate([*parts, np.asarray(flags, dtype=np.float64)])


def episode_differences(env_id: str, n: int, steps: int, **kwargs) -> np.ndarray:
    """Per seed, the largest difference between the single env and its vector sub-env."""
    extra = EXTRA_KEYS[env_id]
    rngs = [np.random.default_rng(10_000 + s) for s in range(n)]
    single = gym.make(env_id, **kwargs)
    a_dim = checks.space_shape("action_space", single.action_space)[0]
    actions = np.stack([r.uniform(-1, 1, size=(steps, a_dim)) for r in rngs]).astype(np.float32)
    ref = []
    for s in range(n):
        obs, info = single.reset(seed=s)
        rows = [_numbers(obs, 0.0, False, False, info, extra)]
        for t in range(steps):
            obs, reward, term, trunc, info = single.step(actions[s, t])
            rows.append(_numbers(obs, reward, term, trunc, info, extra))
            if term or trunc:
                break
        ref.append(rows)
    single.close()
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    # VectorEnv.reset is typed seed: int | None; vector envs take one seed per sub-env
    obs, info = vec.reset(seed=list(range(n)))  # type: ignore[arg-type]  # a list: see above
    worst = np.zeros(n)
    live = np.ones(n, dtype=bool)

    def row(i, obs, reward, term, trunc, info):
        o = {k: v[i] for k, v in obs.items()}
        inf = {k: info[k][i] for k in (*INFO_KEYS, *extra, "is_correction")}
        return _numbers(o, reward[i], term[i], trunc[i], inf, extra)

    zeros = np.zeros(n)
    for i in range(n):
        worst[i] = np.max(np.abs(row(i, obs, zeros, zeros, zeros, info) - ref[i][0]))
    for t in range(steps):
        obs, reward, term, trunc, info = vec.step(actions[:, t])
        for i in np.flatnonzero(live).tolist():
            d = np.max(np.abs(row(i, obs, reward, term, trunc, info) - ref[i][t + 1]))
            worst[i] = max(worst[i], d)
        live &= ~(term | trunc)
        if not live.any():
            break
    vec.close()
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=1000)
    parser.add_argument("--env", choices=["robot", "highway", "both"], default="both")
    args = parser.parse_args()
    names = ["robot", "highway"] if args.env == "both" else [args.env]
    with open("/proc/loadavg") as f:
        print(f"load average at start: {f.read().split()[:3]}")
    for name in names:
        env_id = ENV_IDS[name]
        steps = gym.spec(env_id).max_episode_steps
        assert steps is not None  # both envs register a time limit
        for label, kwargs in SETTINGS.items():
            worst = episode_differences(env_id, args.seeds, steps, **kwargs)
            bad = worst > TOL
            ok = worst[~bad]
            print(
                f"{env_id:18s} {label:28s} diverging episodes {bad.sum():4d} / {len(worst)}"
                f" ({100 * bad.mean():.2f} %); largest difference otherwise "
                f"{ok.max() if len(ok) else float('nan'):.1e}; seeds {np.flatnonzero(bad)[:10]}"
            )


if __name__ == "__main__":
    main()
