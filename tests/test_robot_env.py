"""StROL-Robot-v0: the env contract, the MuJoCo arm and its IK, rendering, the human."""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
import warnings

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from env_checks import rollout, same, unexpected
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.envs.panda.ik import IK_TOL, PandaIK
from strol_gym.envs.panda.model import N_ARM
from strol_gym.envs.robot.env import RobotEnv
from strol_gym.envs.robot.scene import TABLE_TOP, build_model
from strol_gym.envs.robot.seeds import SEED_GRID, _grid, seed_table
from strol_gym.humans import NominalHuman
from strol_gym.priors import FixedPrior
from strol_gym.tasks.robot import RobotTask

ENV_ID = "StROL-Robot-v0"


def make(**kw) -> RobotEnv:
    return gym.make(ENV_ID, **kw).unwrapped


# ------------------------------------------------------------------------------ Gymnasium checks
def test_gymnasium_check_env():
    env = gym.make(ENV_ID)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # Rendering is checked below: check_env would also try render_mode="human", which
        # needs a display.
        check_env(env.unwrapped, skip_render_check=True)
    assert unexpected(caught) == []
    env.close()


def test_sb3_check_env():
    env = gym.make(ENV_ID)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_check_env(env, warn=True)
    assert unexpected(caught) == []
    env.close()


def test_spaces_and_observation_contract():
    env = make()
    obs, info = env.reset(seed=3)
    assert set(obs) == {"state", "correction", "theta_hat", "phi"}
    assert env.observation_space.contains(obs)
    assert obs["state"].shape == (3,) and obs["state"].dtype == np.float32
    np.testing.assert_array_equal(obs["correction"], 0.0)
    np.testing.assert_allclose(obs["theta_hat"], env.task.prior_modes.mean(0))
    assert env.action_space == gym.spaces.Box(-1, 1, (3,), np.float32)
    for key in ("features", "phi", "correction", "robot_action", "theta_star", "theta_hat"):
        assert key in info
    assert info["is_correction"] is False


def test_state_is_the_real_end_effector():
    env = make()
    env.reset(seed=0)
    obs, *_ = env.step(np.array([0.4, -0.3, 0.2]))
    site = env.data.site_xpos[env.ik.site] - np.array([0.0, 0.0, 0.75])
    np.testing.assert_allclose(obs["state"], site, atol=1e-6)
    np.testing.assert_allclose(obs["phi"], env.task.features(site), atol=1e-5)


def test_step_contract_corrections_reward_truncation():
    env = RobotEnv(n_corrections=3, max_episode_steps=6, person={"sigma": 0.1})
    env.reset(seed=1)
    for t in range(6):
        obs, reward, terminated, truncated, info = env.step(np.zeros(3))
        assert info["is_correction"] == (t < 3)
        assert (np.abs(info["correction"]).sum() > 0) == (t < 3)
        np.testing.assert_allclose(obs["correction"], info["correction"], rtol=1e-6, atol=1e-7)
        assert reward == pytest.approx(float(info["phi"] @ info["theta_star"]))
        assert list(info["features"]) == list(env.task.feature_names)
        assert not terminated
        assert truncated == (t == 5)


def test_episode_length_through_make_and_direct():
    for n in (3, 14):
        env = gym.make(ENV_ID, max_episode_steps=n)
        env.reset(seed=0)
        truncs = [env.step(np.zeros(3, dtype=np.float32))[3] for _ in range(n)]
        assert truncs == [False] * (n - 1) + [True]
    assert gym.make(ENV_ID).spec.max_episode_steps == 10
    env = RobotEnv(max_episode_steps=2)
    env.reset(seed=0)
    assert [env.step(np.zeros(3))[3] for _ in range(2)] == [False, True]
    with pytest.raises(ValueError, match="max_episode_steps"):
        RobotEnv(max_episode_steps=0)


def test_action_clipped_and_nan_raises():
    env = make(n_corrections=0)
    env.reset(seed=0)
    *_, info = env.step(np.array([5.0, -7.0, 0.5]))
    np.testing.assert_allclose(info["robot_action"], [0.1, -0.1, 0.05])
    for bad in ([np.nan, 0, 0], [0, np.inf, 0]):
        with pytest.raises(ValueError, match="finite"):
            env.step(np.array(bad))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(2))


def test_an_action_means_the_same_whatever_its_type():
    """float32 and float64 arrays take the env's plain-float path, lists, ints and float16 the
    general one: the same u_R and the same step, in range, clipped or at the bounds."""
    actions = [[0.3, -0.2, 0.9], [5.0, -7.0, 0.5], [1.0, -1.0, -0.0], [0.5, 0.25, -2.0]]
    for a in actions:
        a32 = np.asarray(a, dtype=np.float32)  # one action's numbers, in each form below
        forms = [a32, a32.astype(np.float64), a32.tolist(), [int(v) for v in a32 if v == int(v)]]
        if np.array_equal(a32.astype(np.float16), a32):
            forms.append(a32.astype(np.float16))
        steps = []
        for act in (f for f in forms if len(f) == 3):
            env = make()
            env.reset(seed=3)
            obs, reward, *_, info = env.step(act)
            steps.append((info["robot_action"], obs["state"], reward))
        first = steps[0]
        for other in steps[1:]:
            np.testing.assert_array_equal(other[0], first[0])
            np.testing.assert_array_equal(other[1], first[1])
            assert other[2] == first[2]
    env = make()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.1, np.nan, 0.2], dtype=np.float32))


# ------------------------------------------------------------------------------ arguments
@pytest.mark.parametrize(
    ("kw", "name"),
    [
        ({"person": {"sigma": -0.1}}, "sigma"),
        ({"person": {"bias": float("nan")}}, "bias"),
        ({"prior": "trimodal"}, "prior"),
        ({"prior": [[1.0, 2.0, 3.0]]}, "prior"),
        ({"person": "oracle"}, "unknown human 'oracle'"),
        ({"person": {"name": "boltzmann", "beta": -1.0}}, "beta"),
        ({"n_corrections": -1}, "n_corrections"),
        ({"n_corrections": 2.5}, "n_corrections"),
        ({"render_mode": "ascii"}, "render_mode"),
        ({"width": 8}, "width"),
        ({"height": 5000}, "height"),
        ({"task": "highway"}, "task must be a RobotTask"),
        ({"task": "no-such-task"}, "unknown task"),
        ({"colour": "red"}, "colour"),
    ],
)
def test_bad_kwargs_raise_naming_the_argument(kw, name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # gymnasium's own render_mode warning
        with pytest.raises(ValueError, match=name):
            gym.make(ENV_ID, **kw)


def test_reset_options():
    env = make()
    th, x = np.array([0.3, -0.7]), np.array([0.5, -0.2, 0.3])
    obs, info = env.reset(seed=0, options={"theta_star": th, "state": x})
    np.testing.assert_allclose(info["theta_star"], th)
    np.testing.assert_allclose(obs["state"], x, atol=IK_TOL)
    with pytest.raises(ValueError, match="reset option"):
        env.reset(options={"start": x})


# ------------------------------------------------------------------------------ seeding, pickling
def test_same_seed_same_rollout_and_different_seed_differs():
    a, b = make(person={"sigma": 0.25}), make(person={"sigma": 0.25})
    ra, rb = rollout(a, 7, action_scale=1.2), rollout(b, 7, action_scale=1.2)
    assert same(ra, rb)
    assert not same(ra, rollout(a, 8, action_scale=1.2))


def test_pairing_draws_come_from_env_np_random():
    """Same seed: same θ*, start and human draws, whatever the env did before (paired runs)."""
    a, b = make(person={"sigma": 0.5}), make(person={"sigma": 0.5})
    rollout(b, 123, steps=4, action_scale=1.2)  # b has history; a is fresh
    oa, ia = a.reset(seed=5)
    ob, ib = b.reset(seed=5)
    np.testing.assert_array_equal(ia["theta_star"], ib["theta_star"])
    np.testing.assert_array_equal(oa["state"], ob["state"])
    u = np.array([0.2, 0.1, -0.3])
    np.testing.assert_array_equal(a.step(u)[4]["correction"], b.step(u)[4]["correction"])


def test_pickle_round_trip_continues_identically():
    env = make(person={"sigma": 0.25})
    env.reset(seed=11)
    env.step(np.array([0.5, 0.5, -0.5]))
    clone = pickle.loads(pickle.dumps(env))
    u = np.array([-0.3, 0.8, 0.1])
    for _ in range(3):
        assert same(env.step(u), clone.step(u))


def test_make_vec_sync():
    envs = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="sync")
    obs, _ = envs.reset(seed=0)
    assert obs["state"].shape == (3, 3)
    obs, rew, term, _, _ = envs.step(np.zeros((3, 3), dtype=np.float32))
    assert rew.shape == (3,) and not term.any()
    envs.close()


def test_make_vec_async_spawn():
    envs = gym.make_vec(
        "strol_gym:StROL-Robot-v0",
        num_envs=2,
        vectorization_mode="async",
        vector_kwargs={"context": "spawn"},
        person={"sigma": 0.25},
    )
    obs, info = envs.reset(seed=[1, 2])
    obs, rew, _, _, info = envs.step(np.zeros((2, 3), dtype=np.float32))
    assert obs["state"].shape == (2, 3) and np.isfinite(rew).all()
    assert info["correction"].shape == (2, 3)
    envs.close()


def test_make_in_fresh_subprocess():
    code = (
        "import gymnasium as gym, numpy as np\n"
        "env = gym.make('strol_gym:StROL-Robot-v0')\n"
        "obs, _ = env.reset(seed=0)\n"
        "obs, r, *_ = env.step(np.zeros(3, dtype=np.float32))\n"
        "print(obs['state'].shape, np.isfinite(r))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert "(3,) True" in out.stdout


# ------------------------------------------------------------------------------ rendering
def test_rgb_array_frame_is_not_blank_and_close_releases_it():
    env = make(render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # the scene, not a flat colour
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 50
    env.step(np.array([1.0, 1.0, 1.0]))
    assert not np.array_equal(frame, env.render())  # the arm moved
    env.close()
    assert env._renderer is None


@pytest.mark.skipif(bool(os.environ.get("DISPLAY")), reason="a display exists")
def test_human_render_without_display_fails_politely():
    env = make(render_mode="human")
    with pytest.raises(RuntimeError, match="display"):
        env.reset(seed=0)
    env.close()


HUMAN_RENDER_SCRIPT = """
import gymnasium as gym
import numpy as np
import strol_gym

env = gym.make("StROL-Robot-v0", render_mode="human")
env.reset(seed=0)
for _ in range(3):
    env.step(np.array([0.5, 0.0, -0.5]))
    env.render()
env.close()
print("closed")
"""


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run is not installed")
def test_human_render_under_xvfb_exits_cleanly():
    """close() waits for the passive viewer's thread: without that, GLFW's exit handler
    crashed the interpreter at exit (rc 139) after a clean close."""
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", sys.executable, "-c"]
    done = subprocess.run([*cmd, HUMAN_RENDER_SCRIPT], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert done.stdout.strip().endswith("closed")


# ------------------------------------------------------------------------------ arm and IK
def test_arm_model_matches_the_brief():
    model = build_model(RobotTask())
    assert model.nu >= N_ARM and model.njnt >= N_ARM
    link = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "panda0_link3")
    assert model.body_gravcomp[link] == 1.0
    ik = PandaIK(model)
    assert ik.tilt_deg() < 1.0  # Q_HOME points the gripper down


def test_ik_tracks_a_commanded_velocity():
    """A constant action moves the end effector by action x 0.1 m per step (1 mm tolerance)."""
    env = RobotEnv(n_corrections=0)
    center = 0.5 * (env.task.workspace_low + env.task.workspace_high)
    for action in ([1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-0.5, 0.5, -0.8]):
        a = np.array(action)
        obs, _ = env.reset(seed=0, options={"state": center})
        x = obs["state"].astype(np.float64)
        for _ in range(2):
            obs, *_ = env.step(a)
            new = obs["state"].astype(np.float64)
            np.testing.assert_allclose(new - x, 0.1 * a, atol=1e-3)
            x = new


def test_ik_reaches_random_targets_all_over_the_box():
    env = RobotEnv(n_corrections=0)
    rng = np.random.default_rng(0)
    errors = []
    for ep in range(6):
        env.reset(seed=ep)
        for _ in range(40):
            *_, info = env.step(rng.uniform(-1, 1, 3))
            errors.append(info["ik_error"])
    assert max(errors) < 1e-3
    assert np.median(errors) < IK_TOL


def test_seed_table_reaches_its_grid():
    task = RobotTask()
    table, pts = seed_table(task), _grid(task)
    assert table.shape == (*SEED_GRID, N_ARM) and not np.isnan(table).any()
    ik = PandaIK(build_model(task), lift=TABLE_TOP)
    rng = np.random.default_rng(0)
    for idx in zip(*(rng.integers(0, n, 40) for n in SEED_GRID), strict=True):
        ik.set_q(table[idx])
        assert np.linalg.norm(ik.ee - pts[idx]) < 1e-3


# ------------------------------------------------------------------------------ the human
def test_set_theta_hat_reaches_the_human_and_the_observation():
    seen = []

    class Recorder:
        def __init__(self, task, theta_star, rng):
            self.theta_star = theta_star

        def act(self, x, u_r, theta_hat):
            seen.append(np.array(theta_hat))
            return np.zeros(3)

    env = make(person=Recorder)
    env.reset(seed=0)
    env.step(np.zeros(3))
    np.testing.assert_allclose(seen[-1], env.task.prior_modes.mean(0))
    env.set_theta_hat([0.4, -0.2])
    obs, *_ = env.step(np.zeros(3))
    np.testing.assert_allclose(seen[-1], [0.4, -0.2])
    np.testing.assert_allclose(obs["theta_hat"], [0.4, -0.2])
    with pytest.raises(ValueError, match="theta_hat"):
        env.set_theta_hat([1.0, np.nan])
    env.reset(seed=1)
    np.testing.assert_allclose(env.theta_hat, env.task.prior_modes.mean(0))


def test_default_human_is_nominal_with_the_env_rng_and_boltzmann_works():
    env = make()
    env.reset(seed=0)
    assert isinstance(env.human, NominalHuman) and env.human.rng is env.np_random
    env = make(person={"name": "boltzmann", "beta": 10.0, "sigma": 0.1})
    env.reset(seed=0)
    *_, info = env.step(np.zeros(3))
    assert info["is_correction"] and np.isfinite(info["correction"]).all()


def test_eq_m6_correction_beats_a_random_one():
    """‖θ* − (θ̂ + α g(u_H))‖ is smaller for the nominal human's u_H than for a random u."""
    env = make(n_corrections=1)
    task, rng = env.task, np.random.default_rng(0)
    ours, rand = [], []
    for seed in range(30):
        obs, info = env.reset(seed=seed)
        x = obs["state"].astype(np.float64)
        theta_hat, theta_star = env.theta_hat, info["theta_star"]
        *_, info = env.step(np.zeros(3))
        u_r = info["robot_action"]
        u_rand = rng.uniform(-1, 1, 3) * task.action_bound
        for u, out in ((info["correction"], ours), (u_rand, rand)):
            g = task.g(x, u, u_r)
            out.append(np.linalg.norm(theta_star - (theta_hat + task.alpha * g)))
    ours, rand = np.array(ours), np.array(rand)
    assert ours.mean() < rand.mean()
    assert (ours <= rand + 1e-9).mean() > 0.9


def test_prior_argument_reaches_theta_star():
    env = make(prior=FixedPrior(np.array([[0.25, -0.5]])))
    _, info = env.reset(seed=0)
    np.testing.assert_allclose(info["theta_star"], [0.25, -0.5])
    env = make(prior="uniform")
    draws = np.array([env.reset(seed=s)[1]["theta_star"] for s in range(30)])
    assert (np.abs(draws) <= 1).all() and draws.std() > 0.3


def test_a_task_with_another_box_builds_its_own_seed_table():
    task = RobotTask(
        workspace_low=np.array([0.2, -0.5, 0.05]), workspace_high=np.array([0.7, 0.3, 0.6])
    )
    env = RobotEnv(task=task, n_corrections=0)
    obs, _ = env.reset(seed=0)
    assert (obs["state"] >= task.workspace_low - 1e-3).all()
    rng = np.random.default_rng(0)
    for _ in range(20):
        *_, info = env.step(rng.uniform(-1, 1, 3))
        assert info["ik_error"] < 1e-3
        assert (info["target"] <= task.workspace_high).all()


def test_pickle_after_rendering():
    env = make(render_mode="rgb_array", width=64, height=48)
    env.reset(seed=0)
    env.render()
    clone = pickle.loads(pickle.dumps(env))
    assert clone.render().shape == (48, 64, 3)
    clone.close()
    env.close()
