"""StROL-Highway-v0: the env contract, highway-env integration, rendering, human behaviour."""

from __future__ import annotations

import os

os.environ["SDL_VIDEODRIVER"] = "offscreen"  # before pygame initialises; "dummy" renders blank

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from env_checks import rollout, same, unexpected
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import strol_gym
from strol_gym.envs.highway.env import HighwayEnv, HumanVehicle
from strol_gym.priors import FixedPrior, UniformPrior
from strol_gym.tasks.highway import HIGHWAY_MODES

ENV_ID = "StROL-Highway-v0"


def make(**kw) -> HighwayEnv:
    return gym.make(ENV_ID, **kw).unwrapped


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"person": {"sigma": -0.1}}, "sigma"),
        ({"person": {"sigma": float("nan")}}, "sigma"),
        ({"person": {"bias": float("inf")}}, "bias"),
        ({"prior": "trimodal"}, "prior"),
        ({"prior": [[1.0, 2.0]]}, "prior"),
        ({"person": "reckless"}, "unknown human 'reckless'"),
        ({"person": {"name": "boltzmann", "beta": -1.0}}, "beta"),
        ({"n_corrections": -1}, "n_corrections"),
        ({"n_corrections": 2.5}, "n_corrections"),
        ({"render_mode": "ascii"}, "render_mode"),
        ({"width": 0}, "width"),
        ({"height": 10**6}, "height"),
        ({"task": "robot"}, "task must be a HighwayTask"),
        ({"speed": 3}, "unknown argument"),
    ],
)
def test_bad_kwargs_raise_value_error_naming_the_argument(kwargs, name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # gymnasium warns about an unknown render_mode first
        with pytest.raises(ValueError, match=name):
            gym.make(ENV_ID, **kwargs)


def test_gymnasium_and_sb3_check_env_pass():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(gym.make(ENV_ID).unwrapped, skip_render_check=True)
        sb3_check_env(gym.make(ENV_ID))
    assert unexpected(caught) == []


@pytest.mark.parametrize("human", ["nominal", "boltzmann", "driver"])
def test_same_seed_same_rollout(human):
    a = rollout(make(person={"name": human, "sigma": 0.3, "bias": 0.1}), seed=3)
    b = rollout(make(person={"name": human, "sigma": 0.3, "bias": 0.1}), seed=3)
    assert same(a, b)
    c = rollout(make(person={"name": human, "sigma": 0.3, "bias": 0.1}), seed=4)
    assert not np.array_equal(a[0][0]["state"], c[0][0]["state"])


def test_observation_info_and_contract():
    # gym.make consumes max_episode_steps itself (a TimeLimit wrapper): pass it to the class.
    env = HighwayEnv(n_corrections=3, max_episode_steps=5)
    obs, info = env.reset(seed=0)
    task = env.task
    assert env.observation_space.contains(obs)
    assert obs["state"].shape == (task.state_dim,) and obs["state"].dtype == np.float32
    np.testing.assert_array_equal(obs["correction"], 0.0)
    np.testing.assert_allclose(obs["theta_hat"], HIGHWAY_MODES.mean(0))
    assert set(info) >= {
        "features",
        "phi",
        "correction",
        "robot_action",
        "theta_star",
        "theta_hat",
        "is_correction",
    }
    assert list(info["features"]) == ["gap", "speed", "lane_change"]
    for t in range(5):
        x = env._x.copy()
        obs, reward, term, trunc, info = env.step(np.array([2.0, -0.5], dtype=np.float32))
        assert info["is_correction"] == (t < 3)
        # out-of-range actions are clipped, then scaled to task units
        np.testing.assert_allclose(info["robot_action"], [5.0, -0.01])
        # the env's transition is exactly the Task's f, and the observation is the Task state
        expected = task.dynamics(x, info["correction"], info["robot_action"])
        np.testing.assert_allclose(env._x, expected, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(obs["state"], env._x.astype(np.float32))
        np.testing.assert_allclose(info["phi"], task.features(env._x))
        assert reward == pytest.approx(float(info["phi"] @ info["theta_star"]))
        if t >= 3:
            np.testing.assert_array_equal(obs["correction"], 0.0)
        assert not term
        assert trunc == (t == 4)


def test_set_theta_hat_reaches_the_observation_and_validates():
    env = make()
    env.reset(seed=1)
    env.set_theta_hat([0.2, -0.3, 0.4])
    obs, *_, info = env.step(np.zeros(2, dtype=np.float32))
    np.testing.assert_allclose(obs["theta_hat"], [0.2, -0.3, 0.4], rtol=1e-6)
    np.testing.assert_allclose(info["theta_hat"], [0.2, -0.3, 0.4])
    with pytest.raises(ValueError, match="theta_hat"):
        env.set_theta_hat([1.0, 2.0])
    with pytest.raises(ValueError, match="theta_hat"):
        env.set_theta_hat([1.0, np.nan, 2.0])
    env.reset(seed=1)
    np.testing.assert_allclose(env.theta_hat, HIGHWAY_MODES.mean(0))


def test_nan_action_raises():
    env = make()
    env.reset(seed=0)
    for bad in ([np.nan, 0.0], [0.0, np.inf]):
        with pytest.raises(ValueError, match="finite"):
            env.step(np.array(bad, dtype=np.float32))


def test_priors_and_reset_options():
    env = make(prior="uniform")
    assert isinstance(env.task.prior, UniformPrior)
    draws = np.array([env.reset(seed=s)[1]["theta_star"] for s in range(50)])
    assert (np.abs(draws) <= 1).all() and draws.std(0).min() > 0.3
    env = make(prior=FixedPrior(np.array([0.3, 0.2, 0.1])))
    np.testing.assert_allclose(env.reset(seed=0)[1]["theta_star"], [0.3, 0.2, 0.1])
    star = np.array([1.0, 0.5, -0.5])
    _, info = env.reset(seed=0, options={"theta_star": star})
    np.testing.assert_allclose(info["theta_star"], star)
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(seed=0, options={"speed": 1})


def test_collision_terminates():
    env = make(person="driver")
    state = np.array([112.0, 0.0, 20.0, 0.0, 100.0, 0.0, 35.0, 0.0])  # 12 m behind, 15 m/s faster
    env.reset(seed=0, options={"state": state, "theta_star": [0.0, 1.0, 0.0]})
    for _ in range(10):
        *_, term, _, info = env.step(np.array([-1.0, 0.0], dtype=np.float32))
        if term:
            break
    assert term and info["crashed"]


def test_pickles_mid_episode():
    env = make(person={"sigma": 0.2})
    env.reset(seed=5)
    env.step(np.zeros(2, dtype=np.float32))
    clone = pickle.loads(pickle.dumps(env))
    a = env.step(np.array([0.3, 0.1], dtype=np.float32))
    b = clone.step(np.array([0.3, 0.1], dtype=np.float32))
    assert same(a, b)
    assert isinstance(clone.human_vehicle, HumanVehicle)


def test_make_vec_sync_and_async_spawn():
    for mode, kw in (("sync", {}), ("async", {"context": "spawn"})):
        envs = gym.make_vec(
            f"strol_gym:{ENV_ID}",
            num_envs=2,
            vectorization_mode=mode,
            vector_kwargs=kw,
            person={"sigma": 0.1},
        )
        try:
            obs, _ = envs.reset(seed=[0, 1])
            assert obs["state"].shape == (2, 8)
            for _ in range(3):
                obs, rew, *_ = envs.step(np.zeros((2, 2), dtype=np.float32))
            assert rew.shape == (2,) and np.isfinite(rew).all()
        finally:
            envs.close()


def test_rgb_array_renders_a_non_blank_frame_headless():
    env = gym.make(ENV_ID, render_mode="rgb_array", width=300, height=100)
    env.reset(seed=0)
    env.step(np.zeros(2, dtype=np.float32))
    frame = env.render()
    env.close()
    assert frame.shape == (100, 300, 3) and frame.dtype == np.uint8
    colours = np.unique(frame.reshape(-1, 3), axis=0)
    assert len(colours) > 3 and frame.std() > 5
    green = (frame[..., 1] > 150) & (frame[..., 0] < 100)  # the robot car (highway-env's ego)
    assert green.sum() > 20


def run_episode(human: str, mode: int, seed: int, learn: bool) -> tuple[np.ndarray, np.ndarray]:
    """States of a 10-step episode with the robot holding its lane and speed; θ̂ by Gradient."""
    env = make(person=human)
    start = env.task.sample_episode_start(np.random.default_rng(seed), 1)[0]
    start[[1, 3, 5, 7]] = 0.0  # both cars straight in the left lane's centre
    obs, info = env.reset(seed=seed, options={"theta_star": HIGHWAY_MODES[mode], "state": start})
    learner = strol_gym.make_learner("gradient", task=env.task)
    learner.reset()
    errors = [np.linalg.norm(learner.theta - info["theta_star"])]
    states = [obs["state"].astype(np.float64)]
    for _ in range(10):
        x = obs["state"].astype(np.float64)
        obs, _, term, trunc, info = env.step(np.zeros(2, dtype=np.float32))
        if learn:
            learner.update(x, info["correction"], info["robot_action"])
            env.set_theta_hat(learner.theta)
        errors.append(np.linalg.norm(learner.theta - info["theta_star"]))
        states.append(obs["state"].astype(np.float64))
        assert not term
        if trunc:
            break
    return np.array(states), np.array(errors)


@pytest.mark.parametrize("seed", range(3))
def test_driver_behaviour_follows_theta_star(seed):
    tail, _ = run_episode("driver", 0, seed, learn=False)
    behind = tail[:, 0] - tail[:, 4]
    assert (np.abs(tail[:, 5]) < 1.0).all()  # the tailgater keeps the left lane ...
    assert behind[-1] < behind[0] - 2.0 and 8.0 < behind[-1] < 20.0  # ... and closes in behind
    passer, _ = run_episode("driver", 1, seed, learn=False)
    assert passer[-1, 5] > 2.0  # the passer is in the right lane (y > 2 m) by the end


@pytest.mark.parametrize("mode", [0, 1])
def test_gradient_error_falls_over_a_clean_episode(mode):
    finals = []
    for seed in range(4):
        _, errors = run_episode("nominal", mode, seed, learn=True)
        # a noise-free eq. M6 human (zero action among its candidates) never increases the error
        assert (np.diff(errors) <= 1e-9).all()
        finals.append(errors[-1] / errors[0])
    assert np.mean(finals) < 0.9


def test_make_max_episode_steps_sets_the_episode_length():
    for n in (3, 10, 14):
        env = gym.make("StROL-Highway-v0", max_episode_steps=n)
        env.reset(seed=0)
        steps, done = 0, False
        while not done:
            _, _, term, trunc, _ = env.step(np.zeros(2, dtype=np.float32))
            steps += 1
            done = term or trunc
        assert steps == n or term
    assert gym.make("StROL-Highway-v0").spec.max_episode_steps == 10
    # through gym.make, max_episode_steps=0 is refused by gymnasium's TimeLimit in its own words
    # (a ValueError in 1.4, an AssertionError in 1.2); the env's own check is the class's
    with pytest.raises(ValueError, match="max_episode_steps"):
        HighwayEnv(max_episode_steps=0)
