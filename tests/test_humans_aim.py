"""The aimed person (strol_gym.humans.aim): its density, its fit, its shipped values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from strol_gym.benchmarks.sessions import fitting as F
from strol_gym.humans import HumanSpec, human_model, make_human
from strol_gym.humans.aim import (
    FITTED_AIM,
    AimedModel,
    aim_direction,
    log_direction_density,
    steepest_ascent,
    unit_rows,
)
from strol_gym.tasks import make_task


def _sphere_mean(a: int, mu: np.ndarray, scale: np.ndarray, n: int = 100_000) -> float:
    """∫ p(d) dS by Monte Carlo over uniform directions (area × mean density)."""
    rng = np.random.default_rng(0)
    d = unit_rows(rng.standard_normal((n, a)))
    p = np.exp(log_direction_density(d, np.broadcast_to(mu, (n, a)), scale))
    area = 2 * math.pi ** (a / 2) / math.gamma(a / 2)
    return float(p.mean() * area)


@pytest.mark.parametrize(("a", "aim", "turn"), [(3, 0.8, 1.0), (6, 1.2, 0.5), (6, 3.0, 2.0)])
def test_direction_density_integrates_to_one(a, aim, turn):
    w = np.ones(a)
    w[3:] = turn
    mu = w * unit_rows(np.arange(1.0, a + 1.0)[None])[0]
    assert _sphere_mean(a, mu, aim * w) == pytest.approx(1.0, abs=0.02)


def test_steepest_ascent_of_the_study_task_is_the_feature_gradient():
    task = make_task("study-task2")
    rng = np.random.default_rng(3)
    x = task.sample_start(rng, 5)
    theta = np.tile(task.theta_star, (5, 1))
    b = steepest_ascent(task, x, np.zeros((5, 6)), theta)
    h = 1e-6
    fd = np.stack(
        [
            (task.reward(x + h * e, theta) - task.reward(x - h * e, theta)) / (2 * h)
            for e in np.eye(6)
        ],
        axis=1,
    )
    np.testing.assert_allclose(b, fd * task.action_bound, atol=1e-6)


def test_aim_direction_at_a_reach_gains_more_for_a_push_that_long():
    """The best direction for a push of length r raises θ·φ at least as much by that push as
    the steepest ascent does, and more where the features curve."""
    task = make_task("study-task3")
    rng = np.random.default_rng(11)
    x = task.sample_start(rng, 40)
    theta = np.tile(task.theta_star, (40, 1))
    zero = np.zeros((40, 6))
    local = aim_direction(task, x, zero, theta, 0.0)
    far = aim_direction(task, x, zero, theta, 3.0)
    np.testing.assert_allclose(np.linalg.norm(far, axis=1), 1.0)

    def gain(d):
        return np.einsum("nd,nd->n", task.g(x, 3.0 * d * task.action_bound, zero), theta)

    assert np.all(gain(far) >= gain(local) - 1e-9)
    assert np.mean(gain(far) > gain(local) + 1e-3) > 0.5


def _corrections(task, model, n, seed):
    rng = np.random.default_rng(seed)
    x = task.sample_start(rng, n)
    star = np.tile(task.theta_star, (n, 1))
    u = model.correct(x, np.zeros((n, task.action_dim)), star, rng)
    people = n // 50
    return F.Corrections(
        task,
        x,
        u,
        np.zeros_like(u),
        star,
        np.full_like(star, np.nan),
        np.zeros(n, dtype=int),
        np.arange(n) // 5,
        np.arange(n) % people,
        [f"p{i}" for i in range(people)],
    )


def test_fit_recovers_the_aim_the_turn_the_sizes_and_the_emphasis():
    task = make_task("study-task2")
    truth = {"aim": 0.6, "turn": 0.5, "size": 1.3, "size_sd": 0.45}
    truth |= {"small_share": 0.15, "small_size": 0.25}
    model = AimedModel(task, emphasis=[1.0, 2.0, 0.3, 0.5], **truth)
    data = _corrections(task, model, 800, seed=7)
    fam = F.family("aimed")
    prep = F.prepare(fam, data)
    est, _ = F.maximise(fam, prep)
    for k, v in truth.items():
        assert est[k] == pytest.approx(v, rel=0.25), k
    assert est["w_plate"] == pytest.approx(2.0, rel=0.3)
    assert est["w_table"] == pytest.approx(0.3, rel=0.4)
    sim = F.simulate("aimed", data, est, np.random.default_rng(1))
    real_size = np.median(np.linalg.norm(data.u_h / task.action_bound, axis=1))
    sim_size = np.median(np.linalg.norm(sim / task.action_bound, axis=1))
    assert sim_size == pytest.approx(real_size, rel=0.1)


def test_fitted_aimed_takes_its_study_tasks_values_and_overrides():
    for number in (1, 2, 3):
        task = make_task(f"study-task{number}")
        model = human_model("fitted-aimed", task)
        est = FITTED_AIM["per_task"][f"study-task{number}"]["estimate"]
        assert model.aim == est["aim"] and model.size == est["size"]
        assert model.reach == est["reach"]
        assert model.emphasis[1] == est.get("w_plate", 1.0)
    task = make_task("study-task2")
    assert human_model("fitted-aimed", task, aim=0.3).aim == 0.3
    other = make_task("robot")
    assert human_model("fitted-aimed", other).aim == FITTED_AIM["params"]["aim"]


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"aim": 50.0}, "aim must be"),
        ({"size": 0.0}, "size must be"),
        ({"turn": -1.0}, "turn must be"),
        ({"small_share": 2.0}, "small_share must be"),
        ({"reach": -1.0}, "reach must be"),
        ({"emphasis": [1.0, 2.0]}, "emphasis"),
        ({"emphasis": [0.0, 0.0, 0.0, 0.0]}, "emphasis must be"),
    ],
)
def test_bad_parameters_name_themselves(kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        AimedModel(make_task("study-task2"), **kwargs)


def test_one_person_is_reproducible_and_through_the_spec():
    task = make_task("study-task3")
    x, ur = task.sample_start(np.random.default_rng(0), 1)[0], np.zeros(6)
    a = make_human("fitted-aimed", task, task.theta_star, np.random.default_rng(5))
    b = HumanSpec("fitted-aimed").make(task, task.theta_star, np.random.default_rng(5))
    assert b is not None
    ua, ub = a.act(x, ur, None), b.act(x, ur, None)
    assert ua.shape == (6,) and np.array_equal(ua, ub)
