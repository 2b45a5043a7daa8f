"""The zoo of correction models (strol_gym.humans.zoo): each does what its docstring says,
measured from outside (its corrections against the teacher's on the same candidates), keeps the
paired-run promise, runs by name in the envs, in ĝ training and in ``strol-bench``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.benchmarks import cli
from strol_gym.humans import HUMANS, human_model, make_human
from strol_gym.humans.zoo import ZOO
from strol_gym.learners.registry import make_learner
from strol_gym.learners.training import TrainConfig, sample_batch, train_correction
from strol_gym.priors import FixedPrior
from strol_gym.tasks.highway import HighwayTask
from strol_gym.tasks.robot import RobotTask
from strol_gym.testing import check_human
from strol_gym.wrappers import OnlineLearningWrapper

SEED = 1000  # the diagnostics seed range
N = 3000
TASK = RobotTask()


def _batch(task, n=N, seed=SEED):
    """n people: states, robot actions, θ* from the prior, θ̂ at the modes' mean."""
    rng = np.random.default_rng([seed, 7])
    x = task.sample_start(rng, n)
    u_r = rng.uniform(-1, 1, (n, task.action_dim)) * task.robot_action_bound
    star = task.prior.sample(rng, n)
    hat = np.broadcast_to(np.asarray(task.prior_modes).mean(0), (n, task.dim)).copy()
    return x, u_r, star, hat


def _correct(name, task, x, u_r, star, hat, seed=SEED, **params):
    model = human_model(name, task, **params)
    return model.correct(x, u_r, star, np.random.default_rng(seed), theta_hat=hat)


@pytest.mark.parametrize("task", [RobotTask(), HighwayTask()], ids=["robot", "highway"])
@pytest.mark.parametrize("name", sorted(ZOO))
def test_zoo_member_is_a_registered_human(name, task):
    assert name in HUMANS.names()
    check_human(name, task, sigma=0.1)


def test_skipping_rate_is_p_and_skips_are_exact_zeros():
    x, u_r, star, hat = _batch(TASK)
    for p in (0.0, 0.3, 0.8):
        u = _correct("skipping", TASK, x, u_r, star, hat, sigma=0.1, p=p)
        zero = np.all(u == 0.0, axis=1)
        assert abs(zero.mean() - p) < 4 * np.sqrt(p * (1 - p) / N) + 1e-9, (p, zero.mean())
        # the rest are the teacher's corrections with its noise, on the same draws
        teach = _correct("nominal", TASK, x, u_r, star, hat, sigma=0.1)
        assert not np.array_equal(teach[~zero], u[~zero]) or p == 0.0  # noise draw shifted
        assert np.all(np.any(u[~zero] != 0.0, axis=1))


@pytest.mark.parametrize(("name", "scale"), [("over", 2.0), ("over", 3.5), ("under", 0.5)])
def test_over_and_under_scale_the_teachers_correction(name, scale):
    x, u_r, star, hat = _batch(TASK)
    teach = _correct("nominal", TASK, x, u_r, star, hat)
    u = _correct(name, TASK, x, u_r, star, hat, scale=scale)
    np.testing.assert_allclose(u, scale * teach, rtol=0, atol=1e-15)
    moved = np.linalg.norm(teach, axis=1) > 0
    ratio = np.linalg.norm(u[moved], axis=1) / np.linalg.norm(teach[moved], axis=1)
    np.testing.assert_allclose(ratio, scale, rtol=1e-12)
    # with noise, the difference from the teacher is (scale - 1) u*: the noise is the hand's
    noisy_t = _correct("nominal", TASK, x, u_r, star, hat, sigma=0.3)
    noisy_u = _correct(name, TASK, x, u_r, star, hat, sigma=0.3, scale=scale)
    np.testing.assert_allclose(noisy_u - noisy_t, (scale - 1) * teach, atol=1e-12)


def test_mistaken_teaches_toward_a_wrong_theta_at_its_rate():
    wrong = np.array([-1.5, -1.5])  # a point prior: every mistake teaches toward it
    task = TASK.with_prior(FixedPrior(wrong[None]))
    x, u_r, _, hat = _batch(TASK)
    star = TASK.prior.sample(np.random.default_rng(SEED), N)
    toward_star = _correct("nominal", task, x, u_r, star, hat)
    toward_wrong = _correct("nominal", task, x, u_r, np.broadcast_to(wrong, star.shape), hat)
    differ = np.any(toward_star != toward_wrong, axis=1)
    assert differ.mean() > 0.9  # the two teachers disagree: mistakes are visible
    for rate in (0.0, 0.2, 0.6, 1.0):
        u = _correct("mistaken", task, x, u_r, star, hat, rate=rate)
        is_star = np.all(u == toward_star, axis=1)
        is_wrong = np.all(u == toward_wrong, axis=1)
        assert np.all(is_star | is_wrong)  # every correction teaches one of the two
        frac = is_wrong[differ].mean()
        assert abs(frac - rate) < 4 * np.sqrt(rate * (1 - rate) / differ.sum()) + 1e-9


def test_myopic_maximises_the_next_states_reward_and_differs_from_the_teacher():
    x, u_r, star, hat = _batch(TASK)
    my = _correct("myopic", TASK, x, u_r, star, hat)
    teach = _correct("nominal", TASK, x, u_r, star, hat)

    def value(u):
        return np.einsum("nd,nd->n", TASK.features(TASK.dynamics(x, u, u_r)), star)

    assert np.all(value(my) >= value(teach) - 1e-12)
    # It ignores θ̂: with θ̂ next to θ* the teacher corrects little, the myopic person as much
    near = star + 0.05 * np.random.default_rng(SEED).standard_normal(star.shape)
    teach_near = _correct("nominal", TASK, x, u_r, star, near)
    my_near = _correct("myopic", TASK, x, u_r, star, near)
    np.testing.assert_array_equal(my_near, my)
    assert np.mean(np.any(my_near != teach_near, axis=1)) > 0.9
    size = np.linalg.norm(my_near, axis=1).mean() / np.linalg.norm(teach_near, axis=1).mean()
    assert size > 1.5


@pytest.mark.parametrize("noise_with", ["g", "cup_distance"])
def test_feature_noise_grows_with_g_or_the_feature(noise_with):
    x, u_r, star, hat = _batch(TASK)
    clean = _correct("nominal", TASK, x, u_r, star, hat)
    u = _correct("feature-noise", TASK, x, u_r, star, hat, kappa=0.5, noise_with=noise_with)
    spread = np.linalg.norm(u - clean, axis=1)
    if noise_with == "g":
        size = np.linalg.norm(TASK.g(x, clean, u_r), axis=1)
        assert np.all(spread[size == 0] == 0)  # "no correction" carries no noise at σ = 0
    else:
        size = -TASK.features(x)[:, 1]
    lo, hi = np.quantile(size, [1 / 3, 2 / 3])
    small, large = spread[size <= lo], spread[size >= hi]
    assert np.sqrt(np.mean(large**2)) > 1.5 * np.sqrt(np.mean(small**2))
    # at κ = 0 it is the teacher with σ
    flat = _correct("feature-noise", TASK, x, u_r, star, hat, sigma=0.2, kappa=0.0)
    np.testing.assert_array_equal(flat, _correct("nominal", TASK, x, u_r, star, hat, sigma=0.2))


@pytest.mark.parametrize(
    ("name", "params", "active"),
    [
        ("early", {"until": 2}, [1, 1, 0, 0, 0]),
        ("late", {"start": 3}, [0, 0, 0, 1, 1]),
        ("early", {"until": 1}, [1, 0, 0, 0, 0]),
        ("late", {"start": 0}, [1, 1, 1, 1, 1]),
    ],
)
def test_early_and_late_correct_only_in_their_window(name, params, active):
    env = gym.make("StROL-Robot-v0", person={"name": name, "sigma": 0.1, "kwargs": params})
    try:
        env.reset(seed=SEED)
        seen = [env.step(np.zeros(3, dtype=np.float32))[4] for _ in range(5)]
    finally:
        env.close()
    assert all(i["is_correction"] for i in seen)  # the env still counts the step
    given = [int(np.any(i["correction"] != 0)) for i in seen]
    assert given == active


@pytest.mark.parametrize("name", sorted(ZOO))
def test_same_seed_same_bytes_and_draws_do_not_depend_on_theta_hat(name):
    x, u_r, star, hat = _batch(TASK, n=16)
    model = human_model(name, TASK, sigma=0.2)
    a_rng, b_rng = np.random.default_rng(SEED), np.random.default_rng(SEED)
    a = model.correct(x, u_r, star, a_rng, theta_hat=hat)
    b = model.correct(x, u_r, star, b_rng, theta_hat=hat)
    assert a.tobytes() == b.tobytes()
    c_rng = np.random.default_rng(SEED)
    model.correct(x, u_r, star, c_rng, theta_hat=-hat)  # another learner's estimate
    assert c_rng.bit_generator.state == a_rng.bit_generator.state  # the same draws taken
    # a vector env's per-person draws give each person the bytes a single env gives
    rngs = [np.random.default_rng([SEED, b]) for b in range(4)]
    batched = model.corrections(x[:4], u_r[:4], star[:4], model.draw_each(rngs), hat[:4], k=0)
    for b in range(4):
        one = make_human(name, TASK, star[b], np.random.default_rng([SEED, b]), sigma=0.2)
        assert one.act(x[b], u_r[b], hat[b]).tobytes() == batched[b].tobytes()


@pytest.mark.parametrize(
    ("name", "params", "message"),
    [
        ("skipping", {"p": 1.5}, "p must be a probability in"),
        ("skipping", {"p": "x"}, "p must be a probability in"),
        ("mistaken", {"rate": -0.1}, "rate must be a probability in"),
        ("over", {"scale": 0.5}, r"scale must be a number in \[1, 10\]"),
        ("under", {"scale": 0.0}, r"scale must be a number in \(0, 1\]"),
        ("under", {"scale": True}, "scale must be a number"),
        ("early", {"until": 0}, "until must be an integer >= 1"),
        ("late", {"start": -1}, "start must be an integer >= 0"),
        ("late", {"start": 1.5}, "start must be an integer >= 0"),
        ("feature-noise", {"kappa": -1}, "kappa must be a number in"),
        ("feature-noise", {"noise_with": "speed"}, "noise_with must be one of"),
    ],
)
def test_bad_parameters_name_the_argument(name, params, message):
    with pytest.raises(ValueError, match=message):
        human_model(name, TASK, **params)


def test_a_skipped_correction_leaves_the_rules_where_they_were():
    """u_H = 0: g = 0, so Gradient, One, MOF, StROL and e2e keep θ̂; the Bayesian learner
    reads "no correction" as evidence."""
    moved = {}
    for learner in ("gradient", "one", "mof", "e2e", "strol", "bayes"):
        env = gym.make(
            "StROL-Robot-v0", person={"name": "skipping", "kwargs": {"p": 1.0}, "sigma": 0.3}
        )
        w = OnlineLearningWrapper(env, make_learner(learner, task=env.unwrapped.task))
        try:
            w.reset(seed=SEED)
            theta0 = np.array(w.learner.theta)
            for _ in range(5):
                info = w.step(np.zeros(3, dtype=np.float32))[4]
                assert info["is_correction"] and not np.any(info["correction"])
            moved[learner] = not np.array_equal(theta0, w.learner.theta)
        finally:
            w.close()
    assert moved == {learner: learner == "bayes" for learner in moved}


@pytest.mark.parametrize("env_id", ["StROL-Highway-v0"])
@pytest.mark.parametrize("name", sorted(ZOO))
def test_zoo_member_runs_by_name_in_the_highway_env(name, env_id):
    env = gym.make(env_id, person={"name": name, "sigma": 0.1}, n_corrections=3)
    try:
        env.reset(seed=SEED)
        for _ in range(3):
            info = env.step(np.zeros(2, dtype=np.float32))[4]
            assert np.isfinite(info["correction"]).all()
    finally:
        env.close()


@pytest.mark.parametrize("name", sorted(ZOO))
def test_zoo_member_trains_g_hat(name):
    _, history = train_correction(
        TASK, quiet=True, human=name, steps=2, batch=16, hidden=(8,), n_candidates=16
    )
    assert np.isfinite(history["loss"]).all()
    assert history["config"]["human"] == name
    # training asks for first corrections (k = 0): the late person gives none, the early one
    # corrects like the teacher
    config = TrainConfig(human=name, n_candidates=16)
    u_h = sample_batch(TASK, np.random.default_rng(SEED), 64, config)["u_h"]
    assert (not np.any(u_h)) == (name == "late")


def test_list_shows_the_zoo_with_a_description(capsys):
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    for name in ZOO:
        line = next((ln for ln in out.splitlines() if ln.strip().startswith(f"{name} ")), None)
        assert line is not None, name
        assert len(line.split(None, 1)[1]) > 10  # a description follows the name


@pytest.mark.parametrize("name", sorted(ZOO))
def test_run_by_name(name, tmp_path, capsys):
    out = tmp_path / name
    argv = ["run", "--env", "robot", "--human", name, "--runs", "2", "--block", "2"]
    argv += ["--learners", "gradient,strol", "--jobs", "1", "--quiet", "--no-plots"]
    assert cli.main([*argv, "--seed", str(SEED), "--out", str(out)]) == 0
    assert (out / "runs.csv").is_file()
    assert f"{name} person" in (out / "summary.md").read_text()


@pytest.mark.parametrize(
    "kwargs",
    [
        {"person": {"name": "mistaken", "sigma": 0.2, "kwargs": {"rate": 0.5}}},
        {"person": {"name": "early", "sigma": 0.2, "kwargs": {"until": 2}}},
        {"person": {"name": "feature-noise", "sigma": 0.1}},
    ],
    ids=["mistaken", "early", "feature-noise"],
)
def test_vector_env_batches_the_zoo_as_single_envs_answer(kwargs):
    """The native vector env asks the model for every sub-env in one call (draw_each): the
    same corrections as gymnasium's SyncVectorEnv of single envs."""
    from test_vector_envs import TOL, rollout, worst_difference

    sync, _ = rollout("StROL-Robot-v0", "sync", 3, SEED, 12, **kwargs)
    vec, _ = rollout("StROL-Robot-v0", "vector_entry_point", 3, SEED, 12, **kwargs)
    assert max(worst_difference(s, v) for s, v in zip(sync, vec, strict=True)) < TOL


@pytest.mark.parametrize("p", [0.0, 1.0])
def test_skipping_in_the_study_env_means_no_push(p):
    """The study's simulated user asks its human model where to push: a skipped correction
    is no push at that decision (docs/humans.md)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # v0 is deprecated, still served
        env = gym.make(
            "StROL-Study-v0",
            task=1,
            person={"name": "skipping", "sigma": 0.25, "kwargs": {"p": p}},
            max_episode_steps=60,
        )
    try:
        env.reset(seed=SEED)
        pushes = sum(
            env.step(np.zeros(env.action_space.shape, dtype=np.float32))[4]["is_correction"]
            for _ in range(60)
        )
    finally:
        env.close()
    assert (pushes == 0) == (p == 1.0)
