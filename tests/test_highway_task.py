"""HighwayTask: highway-env's kinematics batched, features, g, prior, network input, policy."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from highway_env.road.lane import StraightLane
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.kinematics import Vehicle

from strol_gym.humans import DriverHuman, driver_correction, optimal_correction
from strol_gym.priors import MixturePrior
from strol_gym.tasks import HighwayTask
from strol_gym.tasks import highway as hw
from strol_gym.tasks.base import Task

TASK = HighwayTask()


def random_states(rng: np.random.Generator, n: int) -> np.ndarray:
    """States well beyond the start distribution: any lane, headings, speeds past ±40 m/s."""
    x = TASK.sample_start(rng, n)
    x[:, [1, 5]] = rng.uniform(-3, 7, size=(n, 2))
    x[:, [3, 7]] = rng.uniform(-0.5, 0.5, size=(n, 2))
    x[:, [2, 6]] = rng.uniform(-45, 45, size=(n, 2))
    return x


def highway_env_step(state: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
    """One car through highway-env's own Vehicle.step on a two-lane road."""
    road = Road(RoadNetwork.straight_road_network(lanes=2, length=10_000), np_random=None)
    v = Vehicle(road, state[:2], heading=float(state[3]), speed=float(state[2]))
    v.act({"acceleration": float(u[0]), "steering": float(u[1])})
    v.step(dt)
    return np.array([v.position[0], v.position[1], v.speed, v.heading])


def test_constants_match_highway_env():
    assert Vehicle.LENGTH == hw.CAR_LENGTH and Vehicle.WIDTH == hw.CAR_WIDTH
    assert Vehicle.MAX_SPEED == hw.MAX_SPEED and Vehicle.MIN_SPEED == hw.MIN_SPEED
    assert StraightLane.DEFAULT_WIDTH == hw.LANE_WIDTH


def test_batched_dynamics_match_highway_env_vehicle():
    rng = np.random.default_rng(0)
    x = random_states(rng, 200)
    u_h = rng.uniform(-2, 2, size=(200, 2)) * TASK.action_bound  # also past the bound
    u_r = rng.uniform(-2, 2, size=(200, 2)) * TASK.action_bound
    nxt = TASK.dynamics(x, u_h, u_r)
    for i in range(len(x)):
        np.testing.assert_allclose(
            nxt[i, :4], highway_env_step(x[i, :4], u_r[i], TASK.dt), rtol=1e-12, atol=1e-12
        )
        np.testing.assert_allclose(
            nxt[i, 4:], highway_env_step(x[i, 4:], u_h[i], TASK.dt), rtol=1e-12, atol=1e-12
        )


def test_dynamics_and_g_broadcast_like_the_base_task():
    rng = np.random.default_rng(1)
    x = random_states(rng, 7)
    cand = TASK.candidate_actions(rng, 7, 33)
    u_r = rng.uniform(-1, 1, size=(7, 2)) * TASK.action_bound
    g = TASK.g(x[:, None], cand, u_r[:, None])
    assert g.shape == (7, 34, 3)
    np.testing.assert_allclose(g, Task.g(TASK, x[:, None], cand, u_r[:, None]), atol=1e-12)
    np.testing.assert_allclose(TASK.g(x[0], cand[0, 3], u_r[0]), g[0, 3], atol=1e-12)
    np.testing.assert_array_equal(g[:, 0], 0.0)  # the zero action teaches nothing
    assert TASK.dynamics(x[0], cand[0], u_r[0]).shape == (34, 8)
    np.testing.assert_array_equal(
        hw.bicycle_step(x[:, :4], u_r, TASK.dt), TASK.dynamics(x, np.zeros_like(u_r), u_r)[:, :4]
    )


def test_every_feature_of_g_depends_on_the_human_action():
    rng = np.random.default_rng(2)
    x = TASK.sample_episode_start(rng, 50)
    x[:, 6] = x[:, 2]  # same speeds, at least 20 m behind: the slot is ahead even T later
    x[:, 0] = np.maximum(x[:, 0], x[:, 4] + 20.0)
    x[:, 5] = x[:, 7] = 0.0  # centred, straight: steering right heads into the right lane
    zero = np.zeros((50, 2))
    acc = np.tile([TASK.max_acceleration, 0.0], (50, 1))
    steer = np.tile([0.0, TASK.max_steering], (50, 1))
    g_acc, g_steer = TASK.g(x, acc, zero), TASK.g(x, steer, zero)
    # accelerating closes in on the slot (start gaps exceed it) and raises the speed
    assert (g_acc[:, 0] > 0.1).all() and (g_acc[:, 1] > 0.1).all()
    # steering right moves the predicted position towards the right lane
    assert (g_steer[:, 2] > 0.1).all()


def test_features_are_order_one_at_start_and_zero_at_the_slot():
    x = TASK.sample_episode_start(np.random.default_rng(3), 1000)
    phi = TASK.features(x)
    assert np.abs(phi).max() < 2.5
    slot = np.array([100.0 + TASK.min_gap, 0.0, 25.0, 0.0, 100.0, 0.0, 25.0, 0.0])
    np.testing.assert_allclose(TASK.features(slot), [0.0, 0.0, 0.0], atol=1e-12)
    right = slot.copy()
    right[5] = hw.LANE_WIDTH
    assert TASK.features(right)[2] == pytest.approx(1.0)


def test_one_start_in_plain_floats_is_the_batchs_row():
    """A single env's reset maps its draws to a state in plain floats: the batch's bytes."""
    task = HighwayTask(start_x=(0.0, 1e4))
    u = np.random.default_rng(5).uniform(size=(500, 8))
    u[:3] = [np.zeros(8), np.nextafter(1.0, 0.0) * np.ones(8), np.full(8, 0.5)]
    batch = task._episode_start(u)
    for i in range(len(u)):
        assert task._episode_start(u[i : i + 1]).tobytes() == batch[i : i + 1].tobytes()
    one = [task.sample_episode_starts([np.random.default_rng(s)]) for s in range(20)]
    many = task.sample_episode_starts([np.random.default_rng(s) for s in range(20)])
    assert np.concatenate(one).tobytes() == many.tobytes()


def test_prior_modes_are_the_two_styles_with_jitter():
    assert isinstance(TASK.prior, MixturePrior)
    np.testing.assert_array_equal(TASK.prior_modes, [[1.0, 1.0, 0.1], [0.1, 1.0, 1.0]])
    assert TASK.prior.jitter == 0.1
    np.testing.assert_allclose(TASK.prior.mean, [0.55, 1.0, 0.55])


def test_network_input_is_scale_free():
    rng = np.random.default_rng(4)
    x = TASK.sample_start(rng, 20)
    u = rng.uniform(-1, 1, size=(20, 2)) * TASK.action_bound
    z = TASK.network_input(x, u, u)
    assert z.shape == (20, TASK.network_input_dim) == (20, 10)
    shifted = x.copy()
    shifted[:, [0, 4]] += 1234.5
    np.testing.assert_allclose(TASK.network_input(shifted, u, u), z, atol=1e-9)
    np.testing.assert_allclose(z[:, 8:], u / TASK.action_bound)
    assert z.std(axis=0).min() > 0.05  # every input varies across start states


def test_no_planner_and_pickles():
    x = TASK.sample_start(np.random.default_rng(5), 2)
    with pytest.raises(NotImplementedError):
        TASK.plan(TASK.prior_modes, x)
    with pytest.raises(NotImplementedError):
        TASK.regret(TASK.prior_modes, TASK.prior_modes, x)
    clone = pickle.loads(pickle.dumps(TASK))
    np.testing.assert_array_equal(clone.features(x), TASK.features(x))
    assert clone.describe() == TASK.describe()


def test_bad_geometry_raises():
    with pytest.raises(ValueError, match="dt"):
        HighwayTask(dt=0.0)
    with pytest.raises(ValueError, match="start_gap"):
        HighwayTask(start_gap=(30.0, 20.0))


def test_robot_policy_batched_bounded_and_yields_to_the_predicted_human():
    rng = np.random.default_rng(6)
    x = TASK.sample_start(rng, 12)
    th = TASK.prior.sample(rng, 12)
    u = TASK.robot_policy(x, th)
    assert u.shape == (12, 2)
    assert (np.abs(u) <= TASK.robot_action_bound + 1e-12).all()
    np.testing.assert_allclose(TASK.robot_policy(x[3], th[3])[0], u[3])
    # A faster human 35 m behind in the robot's (left) lane. If θ̂ says it tailgates, the
    # robot moves over to the right lane (keep right); if θ̂ says it will pass on the right,
    # the robot keeps the left lane and its speed.
    behind = np.array([[135.0, 0.0, 25.0, 0.0, 100.0, 0.0, 28.0, 0.0]])
    tailgate, passer = TASK.prior_modes
    assert TASK.robot_policy(behind, tailgate)[0, 1] > 0.5 * TASK.max_steering
    np.testing.assert_allclose(TASK.robot_policy(behind, passer)[0], [0.0, 0.0], atol=1e-9)


def test_driver_follows_theta_in_one_decision():
    rng = np.random.default_rng(7)
    x = TASK.sample_episode_start(rng, 30)
    x[:, 3] = x[:, 7] = 0.0
    x[:, 1] = x[:, 5] = 0.0
    cand = np.broadcast_to(TASK.candidate_actions(rng, 1, 200), (30, 201, 2))
    zero = np.zeros((30, 2))
    tailgate, passer = (np.tile(m, (30, 1)) for m in TASK.prior_modes)
    u_t = driver_correction(TASK, x, zero, tailgate, cand, 4)
    u_p = driver_correction(TASK, x, zero, passer, cand, 4)
    assert (u_p[:, 1] > 0).all()  # the passer steers towards the right lane
    assert np.abs(u_t[:, 1]).mean() < np.abs(u_p[:, 1]).mean()
    h = DriverHuman(TASK, passer[0], np.random.default_rng(0))
    assert h.act(x[0], zero[0], tailgate[0]).shape == (2,)


def test_eq_m6_human_is_batched_over_the_highway_task():
    rng = np.random.default_rng(8)
    x = TASK.sample_start(rng, 16)
    th0 = np.tile(TASK.prior.mean, (16, 1))
    star = TASK.prior.sample(rng, 16)
    cand = TASK.candidate_actions(rng, 16, 256)
    u = optimal_correction(TASK, x, np.zeros((16, 2)), th0, star, cand)
    after = np.linalg.norm(star - (th0 + TASK.alpha * TASK.g(x, u, np.zeros((16, 2)))), axis=1)
    assert (after <= np.linalg.norm(star - th0, axis=1) + 1e-12).all()
    assert after.mean() < 0.8 * np.linalg.norm(star - th0, axis=1).mean()


@pytest.mark.parametrize("kind", ["strol", "e2e"])
def test_shipped_correction_terms_load_and_match_the_training_condition(kind):
    import strol_gym

    learner = strol_gym.make_learner(kind, task=TASK)
    meta = learner.checkpoint_meta
    assert learner.checkpoint.endswith(f"highway_{kind}.safetensors")
    assert meta["task"]["task_id"] == "StROL-Highway-v0"
    training = meta["training"]
    assert (training["sigma"], training["bias"], training["steps"], training["batch"]) == (
        0.1,
        0.0,
        1000,
        100,
    )
    assert training["seed"] >= 10_000  # disjoint from evaluation seeds 0, 1, ...
    assert meta["prior"]["name"] == "bimodal"


def test_shipped_strol_beats_gradient_in_the_training_condition():
    """Paper H1, checked at Task level (eq. M6 human, σ = 0.1, 10 corrections, paired runs)."""
    import strol_gym
    from strol_gym.learners.simulate import simulate_errors

    learners = {k: strol_gym.make_learner(k, task=TASK) for k in ("gradient", "strol")}
    errors = simulate_errors(TASK, learners, n_runs=200, n_corrections=10, sigma=0.1, seed=0)
    diff = errors["strol"] - errors["gradient"]
    assert diff.mean() < 0 and np.mean(diff < 0) > 0.5
