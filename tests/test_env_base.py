"""The env base every strol-gym env shares: observation, human factories, θ*, wrapper contract."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from test_wrapper import CONTRACT_ID, ContractEnv

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.humans import NominalHuman
from strol_gym.humans.spec import HumanSpec
from strol_gym.learners.rules import GradientLearner
from strol_gym.wrappers import OnlineLearningWrapper

ENV_IDS = ("StROL-Robot-v0", "StROL-Highway-v0")


class Seen:
    """A human factory that records the keyword arguments it receives."""

    def __init__(self) -> None:
        self.calls: list[dict] = []

    def __call__(self, task, theta_star, rng, sigma=0.0, bias=0.0, beta=1.0, tone="calm"):
        self.calls.append({"sigma": sigma, "bias": bias, "beta": beta, "tone": tone})
        return NominalHuman(task, theta_star, rng, sigma=sigma, bias=bias)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_observation_carries_phi_and_matches_the_space(env_id):
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"state", "correction", "theta_hat", "phi"}
    for _ in range(2):
        obs, _, _, _, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        np.testing.assert_allclose(obs["phi"], info["phi"].astype(np.float32))
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_human_factory_gets_sigma_bias_beta_and_its_own_kwargs(env_id):
    seen = Seen()
    person = HumanSpec(seen, sigma=0.2, bias=-0.1, beta=7.0, kwargs={"tone": "stern"})
    env = gym.make(env_id, person=person)
    env.reset(seed=1)
    # (highway-env's constructor resets once itself)
    assert seen.calls and all(
        c == {"sigma": 0.2, "bias": -0.1, "beta": 7.0, "tone": "stern"} for c in seen.calls
    )
    env.close()


def test_a_factory_gets_only_the_arguments_it_declares():
    got = []

    def plain(task, theta_star, rng):  # today's three-argument callables keep working
        got.append(True)
        return NominalHuman(task, theta_star, rng)

    env = gym.make("StROL-Highway-v0", person=plain)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    assert got
    with pytest.raises(ValueError, match=r"^sigma is not a parameter of person .*plain"):
        gym.make("StROL-Highway-v0", person={"name": plain, "sigma": 0.3})


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"kwargs": {"mood": 1}}, r"person kwargs \['mood'\] are not parameters"),
        ({"kwargs": {"sigma": 1}}, "must not hold"),
        ({"kwargs": [1]}, "kwargs must be a dict"),
        ({"name": "no-such-human"}, "unknown human 'no-such-human'"),
        ({"name": "no_such_module:Human"}, "cannot import"),
        ({"name": 3}, "person must be"),
    ],
)
def test_bad_human_arguments_name_the_argument(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make("StROL-Highway-v0", person=kwargs)


class Drifting:
    """A human whose preference changes after its first correction."""

    def __init__(self, task, theta_star, rng):
        self.inner = NominalHuman(task, theta_star, rng)
        self.theta_star = np.asarray(theta_star, dtype=np.float64)

    def act(self, x, u_r, theta_hat):
        u = self.inner.act(x, u_r, theta_hat)
        self.theta_star = -self.inner.theta_star
        return u


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_info_theta_star_is_the_humans_current_preference(env_id):
    env = gym.make(env_id, person=Drifting)
    _, info0 = env.reset(seed=2)
    _, reward, _, _, info = env.step(np.zeros(env.action_space.shape, np.float32))
    np.testing.assert_allclose(info["theta_star"], -info0["theta_star"])
    assert reward == pytest.approx(float(info["phi"] @ info["theta_star"]))
    env.close()


class Recording(GradientLearner):
    """Gradient, remembering the states it learned from."""

    def __init__(self, task, **kw):
        super().__init__(task, **kw)
        self.xs: list[np.ndarray] = []

    def update(self, x, u_h, u_r):
        self.xs.append(np.array(x))
        return super().update(x, u_h, u_r)


class SpanEnv(ContractEnv):
    """A contract env whose corrections report where they began (as the study env does)."""

    def step(self, action):
        start = self.x.copy()
        obs, reward, term, trunc, info = super().step(action)
        info["correction_state"] = start + 0.5
        return obs, reward, term, trunc, info


def test_wrapper_learns_from_correction_state_when_present():
    plain = OnlineLearningWrapper(gym.make(CONTRACT_ID), Recording)
    span = OnlineLearningWrapper(SpanEnv(), Recording)
    obs_p, _ = plain.reset(seed=4)
    obs_s, _ = span.reset(seed=4)
    first_p, first_s = obs_p["state"].astype(np.float64), obs_s["state"].astype(np.float64)
    plain.step(np.zeros(3, np.float32))
    span.step(np.zeros(3, np.float32))
    np.testing.assert_array_equal(plain.learner.xs[0], first_p)
    np.testing.assert_allclose(span.learner.xs[0], first_s + 0.5, atol=1e-6)
