"""StROL-Study-v1 from outside: u_H is the person's push (scripted wrenches), the Panda's limits,
the force reflex, and the deprecation of v0."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.envs.study.controller import VELOCITY_LIMIT
from strol_gym.envs.study.env import StudyEnvV1
from strol_gym.envs.study.geometry import rotation_error
from strol_gym.tasks.study import rpy_to_mat

ENV_ID = "StROL-Study-v1"
SEED = 20001
"""A study seed whose θ̂0's plan the arm follows freely (within the reachable box most do;
docs/study.md gives the share)."""


def make(**kw) -> StudyEnvV1:
    kw.setdefault("person", None)
    return gym.make(ENV_ID, **kw).unwrapped


def steps(env: StudyEnvV1, n: int) -> list[dict]:
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    out = []
    for _ in range(n):
        _, _, _, truncated, info = env.step(zero)
        assert not truncated
        out.append(info)
    return out


def cup_rotation(env: StudyEnvV1) -> np.ndarray:
    """The cup's orientation as seen from outside (MuJoCo's data, or the observed rpy)."""
    return env.data.site_xmat[env._site].reshape(3, 3).copy()


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def push_once(env: StudyEnvV1, force, torque=(0.0, 0.0, 0.0), after: int = 40) -> dict:
    """Follow the plan for ``after`` steps, push for 1 s, return the info of the step the
    correction ended."""
    steps(env, after)
    env.apply_wrench(force, torque, duration=1.0)
    for info in steps(env, 30):
        if info["is_correction"]:
            return info
    raise AssertionError("the push registered no correction")


@pytest.mark.parametrize("task", [1, 2, 3])
def test_lag_while_following_a_plan_is_below_1cm(task):
    env = make(task=task)
    env.reset(seed=SEED)
    infos = steps(env, 100)  # 5 s: the cup touches nothing in that time (docs/study.md)
    lags = [i["lag"] for i in infos]
    moved = np.linalg.norm(infos[-1]["setpoint"][:3] - infos[0]["setpoint"][:3])
    assert moved > 0.2  # it did follow a plan
    assert max(lags) < 0.01


@pytest.mark.parametrize("task", [1, 2, 3])
def test_holding_after_2s_of_a_plan_moves_the_cup_under_2mm(task):
    drift, turn = hold_drift(task, SEED)
    assert drift < 0.002 and turn < 0.01


def hold_drift(task: int, seed: int, reach: bool = True) -> tuple[float, float]:
    """(m, rad) the cup moves in a 1 s hold after 2 s of following θ̂0's plan."""
    env = make(task=task)
    if not reach:
        env.reach = None
    env.reset(seed=seed)
    steps(env, 40)
    env.pause(1.0)
    x0, r0 = env.data.site_xpos[env._site].copy(), cup_rotation(env)
    infos = steps(env, 20)
    assert np.array_equal(infos[0]["setpoint"], infos[-1]["setpoint"])  # held
    drift = np.linalg.norm(env.data.site_xpos[env._site] - x0)
    return float(drift), float(np.linalg.norm(rotation_error(cup_rotation(env), r0)))


def test_the_reachable_box_makes_the_hold_target_hold_on_most_seeds():
    # Task 1, study seeds 20006, 20009, 20011, 20012: without the box θ̂0 plans beyond the
    # elbow's reach and the hold drifts 10-16 mm (docs/study.md).
    seeds = (20006, 20009, 20011, 20012)
    held = [hold_drift(1, s) for s in seeds]
    assert sum(d < 0.002 and r < 0.01 for d, r in held) >= 3
    assert all(hold_drift(1, s, reach=False)[0] > 0.005 for s in seeds[1:2])


@pytest.mark.parametrize("task", [1, 2])
def test_executed_plans_stay_in_the_reachable_box_at_the_planners_pace(task):
    from strol_gym.envs.study.geometry import REACH_ANGLE, REACH_RADIUS, SHOULDER, within_reach
    from strol_gym.tasks import make_task

    t = make_task(f"study-task{task}")
    rng = np.random.default_rng(3)
    env = make(task=task)
    low, high, angle = env.reach
    start = t.start.copy()
    start[:3] += (0.0, 0.1, 0.0)  # outside the box (y > 0.55): left at the planner's pace
    for theta in rng.uniform(-1.0, 1.0, (6, t.dim)):
        raw = t.plan(theta, start)[0]
        plan = within_reach(t, raw, low, high, angle)
        assert np.array_equal(plan[0], raw[0])
        steps_ = np.abs(np.diff(plan, axis=0))
        assert np.all(steps_[:, :3] <= t.plan_pos_bound + 1e-12)
        assert np.all(steps_[:, 3:] <= t.plan_ang_bound + 1e-12)
        inside = plan[12:]  # by then the start, 0.1 m outside, is walked back in
        assert np.all(inside[:, :3] >= low - 1e-12) and np.all(inside[:, :3] <= high + 1e-12)
        # Along the sphere the per-axis step bound cuts its chords by a few mm at most.
        assert np.all(np.linalg.norm(inside[:, :3] - SHOULDER, axis=1) <= REACH_RADIUS + 0.003)
        if t.oriented:
            assert np.all(np.abs(inside[:, 3:5]) <= REACH_ANGLE + 1e-12)
            assert np.allclose(plan[:, 5], raw[:, 5])  # yaw as planned


def pushes_along_each_axis(task, size):
    """(the push, a freshly reset env) for ±x, ±y and ±z, ``size`` long."""
    for axis in range(3):
        for sign in (1.0, -1.0):
            env = make(task=task)
            env.reset(seed=SEED)
            push = np.zeros(3)
            push[axis] = size * sign
            yield push, env


@pytest.mark.parametrize("task", [2, 3])
def test_a_torque_reads_as_a_rotation_about_its_axis(task):
    for torque, env in pushes_along_each_axis(task, 2.0):
        info = push_once(env, (0.0, 0.0, 0.0), torque)
        start, u = info["correction_state"], info["u_h"]
        turn = rotation_error(rpy_to_mat(start[3:] + u[3:]), rpy_to_mat(start[3:]))
        assert angle_deg(turn, torque) < 30.0, (torque, turn)
        assert np.linalg.norm(turn) > 0.02


@pytest.mark.parametrize("task", [1, 2, 3])
def test_a_30N_push_reads_as_a_translation_along_it(task):
    for force, env in pushes_along_each_axis(task, 30.0):
        info = push_once(env, force)
        u = info["u_h"][:3]
        assert angle_deg(u, force) < 15.0, (force, u)
        assert np.linalg.norm(u) >= 0.05  # the arm stays compliant
        assert not info["reflex"] and info["reflexes"] == 0


def test_u_h_is_measured_from_the_held_setpoint():
    env = make(task=1)
    env.reset(seed=SEED)
    steps(env, 40)
    env.apply_wrench((0.0, 30.0, 0.0), duration=1.0)
    zero = np.zeros(3, dtype=np.float32)
    setpoints, seen = [], []
    for _ in range(25):
        obs, _, _, _, info = env.step(zero)
        setpoints.append(info["setpoint"])
        if info["is_correction"]:
            break
        seen.append(obs["state"])
    assert info["is_correction"]
    assert np.allclose(info["correction_state"], setpoints[0])  # held from the first step
    # u_H ends at the pose the person let go of (the last one observed while pushing).
    assert np.allclose(info["correction_state"] + info["u_h"], seen[-1], atol=1e-5)


@pytest.mark.parametrize("task", [1, 2])
def test_a_200N_shove_trips_the_reflex_and_no_joint_exceeds_its_limit(task):
    env = make(task=task)
    env.reset(seed=SEED)
    steps(env, 20)
    x0 = env.data.site_xpos[env._site].copy()
    env.apply_wrench((0.0, -200.0, 0.0), duration=1.0)
    infos, speeds = [], []
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    for _ in range(60):
        _, _, _, truncated, info = env.step(zero)
        assert not truncated and not info["unstable"]
        infos.append(info)
        speeds.append(np.abs(env.data.qvel[:7]) / VELOCITY_LIMIT)
    assert infos[0]["reflex"] and infos[0]["braked"]
    assert sum(i["reflex"] for i in infos) == 1 and infos[-1]["reflexes"] == 1
    braked = [i for i in infos if i["braked"]]
    assert len(braked) >= 20  # held through the 1 s shove, released after it
    assert not infos[-1]["braked"]
    assert not any(i["is_correction"] for i in infos)  # no u_H from a shove
    assert max(s.max() for s in speeds) <= 1.0 + 1e-9
    # Locked while braked: the cup stayed where the reflex caught it.
    assert np.linalg.norm(braked[-1]["setpoint"][:3] - x0) < 0.01


def test_pushes_up_to_60N_never_trip_the_reflex():
    rng = np.random.default_rng(5)
    for force in [*60.0 * np.eye(3), *-60.0 * np.eye(3), *(60.0 * _unit(rng) for _ in range(4))]:
        env = make(task=1)
        env.reset(seed=SEED)
        info = push_once(env, force, after=20)
        assert info["reflexes"] == 0 and np.linalg.norm(info["u_h"]) > 0.05


def _unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def test_reflex_threshold_is_configurable():
    env = make(task=1, reflex_force=40.0)
    env.reset(seed=SEED)
    steps(env, 10)
    env.apply_wrench((50.0, 0.0, 0.0), duration=0.5)
    assert any(i["reflex"] for i in steps(env, 5))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"reflex_force": 0.0}, "reflex_force"),
        ({"reflex_torque": -1.0}, "reflex_torque"),
        ({"reflex_recover": float("nan")}, "reflex_recover"),
        ({"person": "mindreader"}, "unknown human 'mindreader'"),
    ],
)
def test_bad_v1_arguments_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        make(**kwargs)


def test_pause_is_validated():
    env = make()
    env.reset(seed=SEED)
    with pytest.raises(ValueError, match="seconds"):
        env.pause(0.0)


def test_v0_and_v1_are_deprecated_on_make_and_v2_is_not():
    for env_id in ("StROL-Study-v0", ENV_ID):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            gym.make(env_id, person=None).close()
        assert any("out of date" in str(w.message) for w in caught), env_id
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gym.make("StROL-Study-v2", person=None).close()
    assert not any("out of date" in str(w.message) for w in caught)


def test_u_h_is_measured_from_the_cup_where_the_setpoint_is_out_of_reach():
    # Seed 20000's θ̂0 plans beyond the elbow's reach on Task 1: 3.5 s in, the cup trails its
    # setpoint by centimetres; the arm would rest where it is, not at the setpoint.
    env = make(task=1)
    env.reach = None  # the Task's own box: beyond the elbow's reach, as v1 was before it
    env.reset(seed=20000)
    infos = steps(env, 70)
    assert infos[-1]["lag"] > 0.01
    zero = np.zeros(3, dtype=np.float32)
    env.apply_wrench((0.0, 0.0, 30.0), duration=1.0)
    seen = [env._x.copy()]
    for _ in range(30):
        obs, _, _, _, info = env.step(zero)
        if info["is_correction"]:
            break
        seen.append(obs["state"])
    assert info["is_correction"]
    assert np.linalg.norm(info["correction_state"] - info["setpoint"]) > 0.01
    assert np.allclose(info["correction_state"], seen[0], atol=1e-5)


@pytest.mark.parametrize("task", [1, 2])
def test_gymnasium_check_env_and_pickle(task):
    import pickle

    from env_checks import unexpected
    from gymnasium.utils.env_checker import check_env

    env = gym.make(ENV_ID, task=task, max_episode_steps=20)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    assert unexpected(caught) == []
    a = make(task=task, person={"sigma": 0.25})  # with the participant
    a.reset(seed=SEED)
    steps(a, 30)
    b = pickle.loads(pickle.dumps(a))
    zero = np.zeros(a.action_space.shape, dtype=np.float32)
    for _ in range(20):
        oa, ob = a.step(zero)[0], b.step(zero)[0]
        assert all(np.array_equal(oa[k], ob[k]) for k in oa)


def test_versions_are_option_sets_of_one_class_not_overrides():
    import dataclasses

    from strol_gym.envs.study.env import StudyEnv
    from strol_gym.envs.study.versions import V1

    # StudyEnvV1 names its version and nothing else: no method of its own.
    assert not [k for k, v in vars(StudyEnvV1).items() if callable(v) and not k.startswith("__")]

    class StudyEnvV9(StudyEnv):  # a further version: a new option set
        version = dataclasses.replace(V1, number=9, reflex=False)

    assert StudyEnvV9.env_id == "StROL-Study-v9"  # from its version

    env = StudyEnvV9(task=2, person=None, max_episode_steps=3)
    env.reset(seed=1)
    _, _, _, _, info = env.step(np.zeros(env.action_space.shape))
    assert "reflex" not in info and StudyEnvV9.resolve_person({}).name == "observer"
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"person": "observer"}, "'observer' is not one of this version's people"),
        ({"reflex_force": 50.0}, "reflex_force"),
    ],
)
def test_v0_rejects_what_only_later_versions_take(kwargs, named):
    from strol_gym.envs.study.env import StudyEnv

    with pytest.raises(ValueError, match=named):
        StudyEnv(**kwargs)
