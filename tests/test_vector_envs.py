"""The native vector envs equal gymnasium's SyncVectorEnv of the single envs, step for step."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import strol_gym  # noqa: F401  (registers the envs)

TOL = 1e-9


def rollout(env_id: str, mode: str, n: int, seed: int, steps: int, **kwargs) -> tuple:
    env = gym.make_vec(env_id, num_envs=n, vectorization_mode=mode, **kwargs)
    rng = np.random.default_rng(seed)
    first = env.reset(seed=seed)
    out = [first]
    for _ in range(steps):
        # actions beyond [-1, 1] too: both paths must clip them alike
        a = rng.uniform(-1.3, 1.3, size=env.action_space.shape).astype(np.float32)
        out.append(env.step(a))
    spaces = (env.observation_space, env.action_space, env.metadata.get("autoreset_mode"))
    env.close()
    return out, spaces


def worst_difference(a, b, path: str = "") -> float:
    """Largest |a − b| over nested dicts/tuples of arrays; shapes, dtypes, keys and bools exact."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (path, set(a) ^ set(b))
        return max([worst_difference(a[k], b[k], f"{path}/{k}") for k in a], default=0.0)
    if isinstance(a, tuple):
        return max(
            worst_difference(x, y, f"{path}[{i}]")
            for i, (x, y) in enumerate(zip(a, b, strict=True))
        )
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype, (path, a.shape, b.shape, a.dtype, b.dtype)
    if a.dtype == np.bool_:
        assert np.array_equal(a, b), path
        return 0.0
    return float(np.max(np.abs(a.astype(np.float64) - b.astype(np.float64)), initial=0.0))


CASES = [
    ("StROL-Robot-v0", {}),
    ("StROL-Robot-v0", {"person": {"sigma": 0.5, "bias": 0.5}, "n_corrections": 3}),
    ("StROL-Robot-v0", {"person": {"name": "boltzmann", "sigma": 0.25}}),
    ("StROL-Robot-v0", {"person": "changing", "max_episode_steps": 7}),
    ("StROL-Highway-v0", {}),
    ("StROL-Highway-v0", {"person": {"name": "driver", "sigma": 0.5, "bias": 0.5}}),
    # No simulated person: no step corrects, as in the single env.
    ("StROL-Robot-v0", {"person": None}),
    ("StROL-Highway-v0", {"person": None}),
]


@pytest.mark.parametrize(("env_id", "kwargs"), CASES)
@pytest.mark.parametrize("seed", [0, 11])
def test_vector_env_equals_sync_vector_env(env_id, kwargs, seed):
    # 23 steps of 10-step episodes: two whole episodes, two autoresets and a partial third.
    sync, sync_spaces = rollout(env_id, "sync", 4, seed, 23, **kwargs)
    vec, vec_spaces = rollout(env_id, "vector_entry_point", 4, seed, 23, **kwargs)
    assert vec_spaces[0] == sync_spaces[0] and vec_spaces[1] == sync_spaces[1]
    assert vec_spaces[2] == sync_spaces[2] == AutoresetMode.NEXT_STEP
    worst = max(worst_difference(s, v) for s, v in zip(sync, vec, strict=True))
    assert worst < TOL
    # the masks are there and the info is batched as SyncVectorEnv batches it
    info = vec[-1][-1]
    name = next(iter(info["features"]))
    assert info["_phi"].all() and info["features"][f"_{name}"].all()
    assert info["phi"].shape[0] == 4 and info["is_correction"].dtype == np.bool_


def test_vector_robot_corrects_and_autoresets():
    env = gym.make_vec("StROL-Robot-v0", num_envs=3, vectorization_mode="vector_entry_point")
    obs, info = env.reset(seed=5)
    assert obs["state"].shape == (3, 3) and not info["is_correction"].any()
    zeros = np.zeros((3, 3), dtype=np.float32)
    flags = []
    for _ in range(11):
        obs, reward, _, truncated, info = env.step(zeros)
        flags.append((info["is_correction"].copy(), truncated.copy(), reward.copy()))
    assert all(f[0].all() for f in flags[:5]) and not any(f[0].any() for f in flags[5:])
    assert flags[9][1].all() and not any(f[1].any() for f in flags[:9])
    assert np.all(flags[10][2] == 0.0) and not flags[10][0].any()  # the autoreset step
    env.close()


def test_vector_env_rejects_bad_arguments():
    with pytest.raises(ValueError, match="num_envs"):
        gym.make_vec("StROL-Robot-v0", num_envs=0, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="sigma"):
        gym.make_vec(
            "StROL-Robot-v0", 2, vectorization_mode="vector_entry_point", person={"sigma": -1}
        )
    env = gym.make_vec("StROL-Robot-v0", num_envs=2, vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="actions must have shape"):
        env.step(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full((2, 3), np.nan))
    with pytest.raises(ValueError, match="real"):
        env.step(np.full((2, 3), 1j))
    with pytest.raises(ValueError, match="numbers"):
        env.step([["a", "b", "c"]] * 2)
    env.close()


def test_vector_highway_crashes_and_autoresets_like_sync():
    # The "driver" human closes in on the robot car: crashes end sub-envs at different steps,
    # so the autoresets desynchronise; highway-env's impact step must match too.
    kwargs = {"person": {"name": "driver", "sigma": 0.5}}
    sync, _ = rollout("StROL-Highway-v0", "sync", 24, 1, 30, **kwargs)
    vec, _ = rollout("StROL-Highway-v0", "vector_entry_point", 24, 1, 30, **kwargs)
    crashes = sum(int(step[2].sum()) for step in vec[1:])
    assert crashes >= 3
    assert max(worst_difference(s, v) for s, v in zip(sync, vec, strict=True)) < TOL


def test_reset_mask_resets_only_those_sub_envs_like_sync():
    mask = np.array([True, False, True])
    out = []
    for mode in ("sync", "vector_entry_point"):
        env = gym.make_vec("StROL-Highway-v0", 3, vectorization_mode=mode)
        env.reset(seed=3)
        steps = [env.step(np.full((3, 2), 0.3, dtype=np.float32)) for _ in range(4)]
        steps.append(env.reset(seed=[50, None, 52], options={"reset_mask": mask.copy()}))
        steps += [env.step(np.full((3, 2), -0.2, dtype=np.float32)) for _ in range(3)]
        out.append(steps)
        env.close()
    assert max(worst_difference(s, v) for s, v in zip(*out, strict=True)) < TOL
    assert np.array_equal(out[1][4][1]["_phi"], mask)


def test_rectangle_test_is_highway_envs():
    from highway_env import utils
    from highway_env.vehicle.kinematics import Vehicle

    from strol_gym.envs.highway.vector import rectangle_test

    rng = np.random.default_rng(0)
    n = 400
    x = np.zeros((n, 8))
    x[:, 0], x[:, 1] = rng.uniform(0, 8, n), rng.uniform(-3, 3, n)  # robot car near the human
    x[:, 2], x[:, 6] = rng.uniform(10, 30, n), rng.uniform(10, 30, n)
    x[:, 3], x[:, 7] = rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n)
    intersecting, will, translation = rectangle_test(x, 0.5)
    for k in range(n):
        robot = Vehicle(None, x[k, 0:2].copy(), heading=x[k, 3], speed=x[k, 2])
        human = Vehicle(None, x[k, 4:6].copy(), heading=x[k, 7], speed=x[k, 6])
        ref = utils.are_polygons_intersecting(
            robot.polygon(), human.polygon(), robot.velocity * 0.5, human.velocity * 0.5
        )
        assert (intersecting[k], will[k]) == (ref[0], ref[1])
        if ref[1]:
            assert np.abs(translation[k] - ref[2]).max() < 1e-12
    assert 0 < intersecting.sum() < n and will.sum() > intersecting.sum()
