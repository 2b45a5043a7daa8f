"""Priors over θ*: the paper's bimodal prior, uniform, fixed, and make_prior's parsing."""

from __future__ import annotations

import numpy as np
import pytest

from strol_gym.priors import (
    FixedPrior,
    MixturePrior,
    Prior,
    UniformPrior,
    make_prior,
    sample_each,
)
from strol_gym.tasks.robot import ROBOT_MODES


def test_mixture_prior_draws_around_both_modes():
    p = MixturePrior(ROBOT_MODES, jitter=0.1)
    draws = p.sample(np.random.default_rng(0), 4000)
    assert draws.shape == (4000, 2) and p.dim == 2 and isinstance(p, Prior)
    nearest = np.argmin(np.linalg.norm(draws[:, None] - ROBOT_MODES[None], axis=-1), axis=1)
    assert abs(nearest.mean() - 0.5) < 0.03  # equal weights
    resid = draws - ROBOT_MODES[nearest]
    np.testing.assert_allclose(resid.std(axis=0), 0.1, rtol=0.05)
    np.testing.assert_allclose(p.mean, [0.0, 0.0])


def test_mixture_prior_without_jitter_returns_modes_and_is_seeded():
    p = MixturePrior(ROBOT_MODES, jitter=0.0)
    d = p.sample(np.random.default_rng(1), 50)
    assert all(any(np.array_equal(r, m) for m in ROBOT_MODES) for r in d)
    np.testing.assert_array_equal(d, p.sample(np.random.default_rng(1), 50))


@pytest.mark.parametrize(
    ("kw", "name"),
    [
        ({"modes": np.zeros((0, 2))}, "modes"),
        ({"modes": [[np.nan, 0]]}, "finite"),
        ({"modes": ROBOT_MODES, "jitter": -1.0}, "jitter"),
    ],
)
def test_mixture_prior_validates(kw, name):
    with pytest.raises(ValueError, match=name):
        MixturePrior(**kw)


def test_uniform_prior():
    p = UniformPrior(3, low=-0.5, high=2.0)
    d = p.sample(np.random.default_rng(0), 5000)
    assert d.shape == (5000, 3) and d.min() >= -0.5 and d.max() <= 2.0
    np.testing.assert_allclose(d.mean(axis=0), 0.75, atol=0.05)
    np.testing.assert_allclose(p.mean, 0.75)
    with pytest.raises(ValueError, match="dim"):
        UniformPrior(0)
    with pytest.raises(ValueError, match="low < high"):
        UniformPrior(2, low=1.0, high=1.0)


def test_fixed_prior():
    p = FixedPrior(np.array([[0.3, -0.4], [1.0, 1.0]]))
    d = p.sample(np.random.default_rng(0), 100)
    assert {tuple(r) for r in d} == {(0.3, -0.4), (1.0, 1.0)}
    np.testing.assert_allclose(p.mean, [0.65, 0.3])


def test_make_prior_parses_every_form():
    assert make_prior("bimodal", ROBOT_MODES).name == "bimodal"
    np.testing.assert_array_equal(make_prior("bimodal", ROBOT_MODES).modes, ROBOT_MODES)
    assert make_prior("uniform", ROBOT_MODES) == UniformPrior(2)
    fixed = FixedPrior(np.zeros((1, 2)))
    assert make_prior(fixed, ROBOT_MODES) is fixed
    custom = make_prior([[0.5, 0.5]], ROBOT_MODES)
    assert custom.name == "custom" and custom.dim == 2
    with pytest.raises(ValueError, match="prior"):
        make_prior("gaussian", ROBOT_MODES)
    with pytest.raises(ValueError, match="dim"):
        make_prior(UniformPrior(3), ROBOT_MODES)
    with pytest.raises(ValueError, match="columns"):
        make_prior([[1.0, 2.0, 3.0]], ROBOT_MODES)


@pytest.mark.parametrize("prior", [MixturePrior(ROBOT_MODES, jitter=0.1), UniformPrior(2)])
def test_sample_each_is_one_sample_per_generator(prior):
    """A vector env's resets: one θ from each sub-env's generator, as each single env draws it
    (an index with size=1, then its jitter), and each generator left where that leaves it."""
    seeds = [3, 7, 11]
    batched = [np.random.default_rng(s) for s in seeds]
    got = sample_each(prior, batched)
    for s, rng, row in zip(seeds, batched, got, strict=True):
        ref = np.random.default_rng(s)
        if isinstance(prior, MixturePrior):
            idx = ref.integers(0, len(prior.modes), size=1)
            want = prior.modes[idx] + prior.jitter * ref.standard_normal((1, prior.dim))
        else:
            want = ref.uniform(prior.low, prior.high, size=(1, prior.dim))
        np.testing.assert_array_equal(row, want[0])
        assert rng.random() == ref.random()  # the streams continue alike
    alone = np.random.default_rng(seeds[0])  # one generator (a single env's reset): the bytes
    assert sample_each(prior, [alone]).tobytes() == got[:1].tobytes()
    first = np.random.default_rng(seeds[0])
    sample_each(prior, [first, np.random.default_rng(0)])
    assert alone.random() == first.random()  # and the draws
    assert got.shape == (3, 2)
