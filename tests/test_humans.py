"""Simulated humans: the eq. M6 teacher, the Boltzmann human, noise and bias in a_max units."""

from __future__ import annotations

import numpy as np
import pytest

from strol_gym.humans import (
    HUMAN_MODELS,
    BoltzmannHuman,
    Human,
    NominalHuman,
    boltzmann_correction,
    human_factory,
    optimal_correction,
    perturb,
)
from strol_gym.humans.interface import Replayed
from strol_gym.tasks.highway import HighwayTask
from strol_gym.tasks.robot import RobotTask

TASK = RobotTask()


def _batch(n: int, k: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = TASK.sample_start(rng, n)
    u_r = rng.uniform(-1, 1, (n, 3)) * TASK.action_bound
    theta_hat = rng.normal(0, 0.3, (n, 2))
    theta_star = TASK.prior.sample(rng, n)
    cand = TASK.candidate_actions(rng, n, k)
    return x, u_r, theta_hat, theta_star, cand


def _dist(x, u, u_r, theta_hat, theta_star):
    g = TASK.g(x, u, u_r)
    return np.linalg.norm(theta_star - (theta_hat + TASK.alpha * g), axis=-1)


def test_candidates_include_zero_and_respect_the_bound():
    cand = TASK.candidate_actions(np.random.default_rng(0), 4, 100)
    assert cand.shape == (4, 101, 3)
    np.testing.assert_array_equal(cand[:, 0], 0.0)
    assert np.abs(cand).max() <= TASK.step_bound
    with pytest.raises(ValueError, match="k"):
        TASK.candidate_actions(np.random.default_rng(0), 1, -1)


def test_optimal_correction_is_the_best_candidate():
    x, u_r, th, ts, cand = _batch(16, 64)
    u = optimal_correction(TASK, x, u_r, th, ts, cand)
    assert u.shape == (16, 3)
    all_d = _dist(x[:, None], cand, u_r[:, None], th[:, None], ts[:, None])  # (B, K+1)
    np.testing.assert_allclose(_dist(x, u, u_r, th, ts), all_d.min(axis=1))
    # zero is a candidate, so the teacher never moves θ̂ further than "do nothing" would
    assert (_dist(x, u, u_r, th, ts) <= all_d[:, 0] + 1e-12).all()


def test_boltzmann_limits():
    x, u_r, _, ts, cand = _batch(200, 8, seed=1)
    rng = np.random.default_rng(0)
    greedy = boltzmann_correction(TASK, x, u_r, ts, cand, 1e6, rng)
    g = TASK.g(x[:, None], cand, u_r[:, None])
    best = cand[np.arange(200), np.argmax(np.einsum("bkd,bd->bk", g, ts), axis=1)]
    np.testing.assert_allclose(greedy, best)
    # β = 0: uniform over the 9 candidates; the zero action is chosen ~1/9 of the time
    cand0 = np.repeat(cand[:1], 4000, axis=0)
    picks = boltzmann_correction(
        TASK,
        np.repeat(x[:1], 4000, 0),
        np.repeat(u_r[:1], 4000, 0),
        np.repeat(ts[:1], 4000, 0),
        cand0,
        0.0,
        rng,
    )
    frac_zero = np.mean(np.all(picks == 0, axis=1))
    assert abs(frac_zero - 1 / 9) < 0.02


@pytest.mark.parametrize(("sigma", "bias"), [(0.25, 0.0), (0.5, 0.5), (0.1, -0.3)])
def test_perturb_noise_and_bias_are_fractions_of_a_max(sigma, bias):
    rng = np.random.default_rng(0)
    u = np.zeros((20000, 3))
    d = perturb(TASK, u, sigma, bias, rng)
    a_max = TASK.action_bound
    np.testing.assert_allclose(d.std(axis=0), sigma * a_max, rtol=0.03)
    # 4 standard errors of the mean: σ a_max / √20000
    np.testing.assert_allclose(d.mean(axis=0), bias * a_max, atol=4 * sigma * a_max[0] / 141)


def test_perturb_draws_even_without_noise():
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    out = perturb(TASK, np.ones((2, 3)), 0.0, 0.0, a)
    np.testing.assert_array_equal(out, 1.0)
    b.standard_normal((2, 3))
    assert a.random() == b.random()  # same stream position: pairing across noise levels


@pytest.mark.parametrize("cls", [NominalHuman, BoltzmannHuman])
def test_humans_act_shape_seeding_and_protocol(cls):
    ts = np.array([0.8, -0.8])
    x, u_r, th = TASK.start, np.array([0.05, 0.0, -0.05]), np.zeros(2)
    h1 = cls(TASK, ts, np.random.default_rng(7), sigma=0.25)
    h2 = cls(TASK, ts, np.random.default_rng(7), sigma=0.25)
    u1, u2 = h1.act(x, u_r, th), h2.act(x, u_r, th)
    assert u1.shape == (3,) and np.isfinite(u1).all()
    np.testing.assert_array_equal(u1, u2)
    assert not np.array_equal(u1, h1.act(x, u_r, th))  # fresh draws each call
    assert isinstance(h1, Human)
    name = {"NominalHuman": "nominal", "BoltzmannHuman": "boltzmann"}[cls.__name__]
    assert HUMAN_MODELS[name] is cls.model_class and human_factory(name) is cls


@pytest.mark.parametrize(
    ("kw", "name"),
    [({"sigma": -0.1}, "sigma"), ({"bias": np.inf}, "bias"), ({"n_candidates": 0}, "n_candidates")],
)
def test_human_arguments_are_validated(kw, name):
    with pytest.raises(ValueError, match=name):
        NominalHuman(TASK, np.zeros(2), np.random.default_rng(0), **kw)
    with pytest.raises(ValueError, match="beta"):
        BoltzmannHuman(TASK, np.zeros(2), np.random.default_rng(0), beta=-1.0)


def test_nominal_human_teaches_toward_theta_star():
    """Noise-free, θ̂ + α g(u_H) is never further from θ* than θ̂ (zero is a candidate)."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        ts = TASK.prior.sample(rng, 1)[0]
        th = rng.normal(0, 0.5, 2)
        x, u_r = TASK.sample_start(rng, 1)[0], rng.uniform(-0.1, 0.1, 3)
        u = NominalHuman(TASK, ts, rng).act(x, u_r, th)
        after = np.linalg.norm(ts - (th + TASK.alpha * TASK.g(x, u, u_r)))
        assert after <= np.linalg.norm(ts - th) + 1e-12


@pytest.mark.parametrize("task", [RobotTask(), HighwayTask()], ids=["robot", "highway"])
def test_one_persons_perturbation_is_the_batchs_row_to_the_bit(task):
    """One person's noise runs in plain floats: each row equals the batch's, bit for bit."""
    rng = np.random.default_rng(5)
    u = rng.uniform(-1, 1, (200, task.action_dim)) * task.action_bound
    for sigma, bias in [(0.0, 0.0), (0.3, -0.2), (1.7, 0.45)]:
        noise = rng.standard_normal(u.shape)
        batch = perturb(task, u, sigma, bias, Replayed(noise))
        rows = [
            perturb(task, u[i : i + 1], sigma, bias, Replayed(noise[i : i + 1]))
            for i in range(len(u))
        ]
        assert np.concatenate(rows).tobytes() == batch.tobytes()


@pytest.mark.parametrize("task", [RobotTask(), HighwayTask()], ids=["robot", "highway"])
def test_candidates_scale_by_a_max_as_a_broadcast_product_would(task):
    """Candidates are scaled in place by a tiled bound (a view of each person's block), or by
    broadcasting where the block is not contiguous: either way the products of ``u * a_max``."""
    rng = np.random.default_rng(2)
    u = rng.uniform(-1, 1, (5, 33, task.action_dim))
    want = (u * np.asarray(task.action_bound)).tobytes()
    block = u.copy()
    task._scale_candidates(block)
    strided = np.asfortranarray(u)
    task._scale_candidates(strided)
    assert block.tobytes() == want
    assert np.ascontiguousarray(strided).tobytes() == want
