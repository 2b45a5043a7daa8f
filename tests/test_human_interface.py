"""The one human interface: a model answers for a batch; the single-sample ``act``, a vector
env's per-sub-env draws and the teaching loop all go through it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.humans import (
    HUMANS,
    BoltzmannModel,
    HumanModel,
    NominalModel,
    PerSampleModel,
    human_factory,
    human_model,
    make_human,
    register_human,
    teach,
)
from strol_gym.humans.population import batched_corrections
from strol_gym.learners import training
from strol_gym.learners.registry import make_learner
from strol_gym.tasks.robot import RobotTask

TASK = RobotTask()


def _people(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = TASK.sample_start(rng, n)
    u_r = rng.uniform(-1, 1, (n, 3)) * TASK.action_bound
    return x, u_r, rng.normal(0, 0.3, (n, 2)), TASK.prior.sample(rng, n)


@pytest.mark.parametrize("name", ["nominal", "boltzmann", "driver", "changing"])
def test_a_batch_from_each_persons_generator_is_each_persons_act(name):
    """Person b answering alone (``act`` with its generator) gives the bytes the batched call
    gives over draws taken from every person's generator: what a vector env relies on."""
    x, u_r, th, star = _people(6)
    humans = [
        make_human(name, TASK, star[b], np.random.default_rng(100 + b), sigma=0.3, bias=0.1)
        for b in range(6)
    ]
    alone = [
        make_human(name, TASK, star[b], np.random.default_rng(100 + b), sigma=0.3, bias=0.1)
        for b in range(6)
    ]
    for _ in range(3):  # the changing preference switches after 2 corrections
        batch = batched_corrections(humans, x, u_r, th)
        one = np.stack([h.act(x[b], u_r[b], th[b]) for b, h in enumerate(alone)])
        np.testing.assert_array_equal(batch, one)
        assert all((a.theta_star == b.theta_star).all() for a, b in zip(humans, alone, strict=True))


def test_the_batch_from_one_generator_is_the_model_asked_for_the_whole_batch():
    x, u_r, _, star = _people(32)
    model = human_model("boltzmann", TASK, sigma=0.2, beta=20.0)
    assert isinstance(model, BoltzmannModel) and not model.needs_theta_hat
    u1 = model.correct(x, u_r, star, np.random.default_rng(5))
    draws = model.draw(np.random.default_rng(5), 32)
    np.testing.assert_array_equal(u1, model.corrections(x, u_r, star, draws))
    assert not np.array_equal(u1, model.correct(x, u_r, star, np.random.default_rng(6)))
    teacher = human_model("nominal", TASK)
    with pytest.raises(ValueError, match="theta_hat"):
        teacher.correct(x, u_r, star, np.random.default_rng(5))


class _Recorder:
    """A user's single-sample human that records the θ̂ it was given."""

    def __init__(self, task, theta_star, rng, needs=True):
        self.theta_star, self.seen, self.needs_theta_hat = np.asarray(theta_star), [], needs

    def act(self, x, u_r, theta_hat):
        self.seen.append(theta_hat)
        return np.zeros(3)


@pytest.mark.parametrize("needs", [True, False])
def test_the_env_hands_theta_hat_only_to_humans_who_declare_they_need_it(needs):
    made = []

    def factory(task, theta_star, rng):
        made.append(_Recorder(task, theta_star, rng, needs))
        return made[-1]

    env = gym.make("StROL-Robot-v0", person=factory)
    env.reset(seed=0)
    env.step(np.zeros(env.action_space.shape))
    seen = made[-1].seen[0]
    assert (seen is not None) == needs
    if needs:
        assert seen.shape == (2,)


def test_a_registered_model_is_one_file_and_serves_env_training_and_the_loop():
    class Lazy(HumanModel):
        """Corrects half as much as the eq. M6 teacher would."""

        needs_theta_hat = True

        def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
            return 0.5 * NominalModel.choose(self, x, u_r, theta_star, draws, theta_hat, k)

    register_human("test-lazy", Lazy)
    try:
        assert isinstance(human_model("test-lazy", TASK), Lazy)
        env = gym.make("StROL-Robot-v0", person={"name": "test-lazy", "sigma": 0.0})
        obs, _ = env.reset(seed=1)
        obs, *_ = env.step(np.zeros(env.action_space.shape))
        assert np.abs(obs["correction"]).max() <= 0.5 * TASK.step_bound + 1e-6
        cfg = training.TrainConfig(kind="strol", human="test-lazy")
        batch = training.sample_batch(TASK, np.random.default_rng(0), 8, cfg)
        assert batch["u_h"].shape == (8, 3)
        assert human_factory("test-lazy").model_class is Lazy
    finally:
        HUMANS.unregister("test-lazy")


def test_a_plain_factory_is_asked_per_person_in_a_batch():
    model = human_model(lambda task, theta_star, rng: _Recorder(task, theta_star, rng), TASK)
    assert isinstance(model, PerSampleModel)
    x, u_r, th, star = _people(4)
    np.testing.assert_array_equal(model.correct(x, u_r, star, np.random.default_rng(0), th), 0.0)


def test_the_teaching_loop_teaches_and_checks_its_arguments():
    x, _, _, star = _people(64, seed=3)
    learner = make_learner("gradient", task=TASK)
    theta0 = np.broadcast_to(learner.reset(), (64, 2)).copy()
    learner.reset(theta0)
    model = human_model("nominal", TASK, sigma=0.0)
    theta, x_end = teach(TASK, model, star, theta0, x, learner.update, np.random.default_rng(0), 5)
    before = np.linalg.norm(star - theta0, axis=1)
    after = np.linalg.norm(star - theta, axis=1)
    assert np.median(after) < 0.7 * np.median(before)
    assert x_end.shape == x.shape and not np.array_equal(x_end, x)
    with pytest.raises(ValueError, match="n_corrections"):
        teach(TASK, model, star, theta0, x, learner.update, np.random.default_rng(0), -1)
