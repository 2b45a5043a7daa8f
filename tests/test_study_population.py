"""The fitted study population: StROL-Study-v2's default participant, its fit file, the fit on
synthetic sessions in the authors' layout (written here, never their data), rebounds."""

from __future__ import annotations

import itertools
import json
import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from cli_checks import cli_error
from test_study_import import _session, _write

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.benchmarks import cli
from strol_gym.envs.study import population
from strol_gym.envs.study.participant import FittedParticipant
from strol_gym.envs.study.people import FittedParams
from strol_gym.tasks import make_task
from strol_gym.tasks.study import STUDY_TASKS_V2


def _v2(**kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gym.make("StROL-Study-v2", **kwargs)


def test_v2_default_participant_is_the_fitted_population():
    shipped = json.loads(population.FIT_FILE.read_text())
    assert shipped["format"] == population.FORMAT
    assert shipped["n_people"] == 12 and shipped["source"] and shipped["command"]
    pop = population.shipped()
    for name in population.FITTED:
        assert pop.fitted[name] == shipped["fitted"][name]["estimate"]
        lo, hi = shipped["fitted"][name]["ci95"]
        assert lo <= pop.fitted[name] <= hi
    for entry in shipped["prior"].values():
        assert entry["status"] == "prior, not fitted" and entry["source"]
    env = _v2(task=2)
    env.reset(seed=5)
    human = env.unwrapped.person
    assert env.unwrapped.person_spec.name == "fitted"
    assert isinstance(human, FittedParticipant)
    for name, entry in shipped["prior"].items():  # the priors, read back
        if name != "ramp":  # the shipped population's push rises as the real ones logged
            assert getattr(human.params, name) == entry["value"]
    assert human.params.ramp == pop.rise and human.params.correction == "aimed"
    env.close()
    # the between-person distribution read back: draws recover the file's log means and sds
    rng = np.random.default_rng(0)
    people = [pop.draw(rng, 3) for _ in range(4000)]
    for key in ("size", "turn", "aim", "linger"):
        logs = np.log([getattr(p, key) for p in people])
        mean, sd = pop.fitted[f"{key}_log_mean"], pop.fitted[f"{key}_log_sd"]
        assert abs(logs.mean() - mean) < 4 * sd / math.sqrt(len(logs)) + 1e-12
        assert abs(logs.std() - sd) < 0.1 * sd + 1e-12
    assert pop.hazard is not None and all(p.hazard == pop.hazard[3] for p in people)
    # without a timing fit the population keeps the learner-independent budget
    budgeted = population.read_fit(population.FIT_FILE)
    budgets = np.array([budgeted.draw(rng, 3).budget for _ in range(4000)])
    assert abs(budgets.mean() - pop.count_mean[3]) < 4 * math.sqrt(pop.count_mean[3] / 4000)


def test_two_users_draw_different_people_and_a_seed_the_same():
    env = _v2(task=1)
    drawn = []
    for seed in (11, 12, 11):
        env.reset(seed=seed)
        p = env.unwrapped.person.params
        drawn.append((p.size, p.turn, p.aim, p.linger, p.hazard))
    env.close()
    assert drawn[0] != drawn[1]
    assert drawn[0] == drawn[2]


def test_fitted_params_are_checked():
    with pytest.raises(ValueError, match=r"person kwargs\['size'\]"):
        FittedParams(size=-1.0)
    with pytest.raises(ValueError, match=r"person kwargs\['budget'\]"):
        FittedParams(budget=-2)
    with pytest.raises(ValueError, match="participant fit"):
        population.parse({"format": "something else"})


def test_release_keeps_the_push_direction():
    """A cup that overshoots its target while the push is let go is not pushed back (v1's
    participant re-aimed at the target: a second, opposite correction, a rebound)."""
    task = STUDY_TASKS_V2[1]()
    params = FittedParams(budget=3, ramp=0.2)
    p = FittedParticipant(task, task.theta_star, np.random.default_rng(0), params=params)
    x = task.start.copy()
    p.phase, p.target, p._t0, p._level = "push", x + np.array([0.05, 0, 0]), 0.0, 1.0
    p._sizing = p._push_sizes(x)
    p._started = 0.0
    f_push, _ = p.wrench(0.05, x)
    assert f_push[0] > 0
    beyond = x + np.array([0.08, 0, 0])  # overshot: the target is now behind the cup
    p._stalled = lambda t, x: True  # the person lets go now
    forces = []
    t = 0.1
    while p.phase != "idle":
        f, _ = p.wrench(t, beyond)
        forces.append(f)
        t += 0.05
    assert all(f[0] >= 0 and abs(f[1]) < 1e-12 for f in forces)  # never pushed back
    assert p.made == 1


def test_the_participant_keeps_what_it_meant():
    """Every push's correction as drawn (a_max units) is kept for the read scale."""
    task = STUDY_TASKS_V2[1]()
    p = FittedParticipant(task, task.theta_star, np.random.default_rng(0), params=FittedParams())
    u = p.act(task.start, np.zeros(3))
    assert len(p.intended) == 1 and p.intended[0].shape == (3,)
    np.testing.assert_allclose(u, p.intended[0] * task.action_bound)


def test_a_face_the_cup_is_past_does_not_pull_the_target_back():
    """At a pose outside the planning box (v2's arm reaches y 0.65 > 0.6), a push's target
    is not dragged back inside: the box widened to hold the cup bounds it."""
    task = STUDY_TASKS_V2[1]()
    p = FittedParticipant(task, task.theta_star, np.random.default_rng(0), params=FittedParams())
    x = np.array([0.25, 0.65, 0.30])
    outward = p._target(x, np.array([0.0, 0.05, -0.05]))
    np.testing.assert_allclose(outward, [0.25, 0.65, 0.25])  # held at the cup's y, not 0.6
    inward = p._target(x, np.array([0.0, -0.05, 0.0]))
    np.testing.assert_allclose(inward, [0.25, 0.60, 0.30])
    assert np.array_equal(p._target(task.start, np.zeros(3)), task.dynamics(task.start, 0, 0))


def test_no_rebounds_on_v2():
    """Fitted people pushing v2's arm: no correction starts < 0.3 s after the last one ended
    opposite to it (v1's participant: 22 % on Task 1)."""
    records = []
    for task, seed in ((1, 3), (2, 4)):
        env = _v2(task=task, duration=25.0)
        env.reset(seed=seed)
        env.unwrapped.person.params = FittedParams(
            **{**env.unwrapped.person.params.__dict__, "budget": 6, "hazard": None}
        )
        zero = np.zeros(env.action_space.shape, dtype=np.float32)
        truncated, recs = False, []
        while not truncated:
            _, _, _, truncated, info = env.step(zero)
            if info["is_correction"]:
                recs.append(info["correction_record"])
        env.close()
        records.append(recs)
    n = sum(len(r) for r in records)
    assert n >= 4  # people pushed
    rebounds = sum(
        b["start_time"] - a["end_time"] < 0.3 and float(a["u_h"] @ b["u_h"]) < 0
        for recs in records
        for a, b in itertools.pairwise(recs)
    )
    assert rebounds == 0


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Four people × Tasks 1-3 × every learner in the authors' layout, person p's corrections
    all moving the cup 0.05·(p+1) m; imported with import-study."""
    root = tmp_path_factory.mktemp("authors") / "data"
    rng = np.random.default_rng(39)
    for p in range(4):
        for task in (1, 2, 3):
            for alg in ("b1", "b2", "ours"):
                moves = []
                for _ in range(2):
                    d = rng.normal(size=3)
                    pos = d / np.linalg.norm(d) * 0.05 * (p + 1)
                    turn = rng.uniform(-0.1, 0.1, 3) if task > 1 else np.zeros(3)
                    moves.append(np.concatenate([pos, turn]))
                _write(root, f"user_{p + 1}", task, alg, _session(task, rng, moves, [5, 0, 1, 3]))
    out = tmp_path_factory.mktemp("logs") / "logs"
    assert cli.main(["import-study", str(root), "--out", str(out)]) == 0
    return out


def test_fit_on_synthetic_sessions(logs, tmp_path, capsys):
    out = tmp_path / "fit.json"
    argv = ["fit-participant", str(logs), "--out", str(out), "--bootstrap", "20"]
    assert cli.main(argv) == 0
    assert "corrections per session, Task 1" in capsys.readouterr().out
    fit = json.loads(out.read_text())
    assert fit["n_people"] == 4 and fit["n_sessions"] == 36 and fit["n_corrections"] == 72
    for t in ("1", "2", "3"):  # four corrections logged per session (empty and one-pose too)
        assert fit["fitted"]["count_mean"][t]["estimate"] == pytest.approx(4.0)
    sizes = np.log([0.5, 1.0, 1.5, 2.0])  # each person's displacement in a_max units
    f = fit["fitted"]
    assert f["size_log_mean"]["estimate"] == pytest.approx(sizes.mean(), abs=1e-6)
    assert f["size_log_sd"]["estimate"] == pytest.approx(sizes.std(ddof=1), abs=1e-6)
    assert f["size_within"]["estimate"] == pytest.approx(0.0, abs=1e-6)
    assert f["count_person_sd"]["estimate"] == 0.0  # every person made as many
    assert set(fit["heldout"]) == {"size", "turn", "aim", "linger", "count"}
    assert all(v["status"] == "prior, not fitted" for v in fit["prior"].values())
    pop = population.read_fit(out)  # the env's reader takes it
    assert pop.count_mean == {1: 4.0, 2: 4.0, 3: 4.0}
    assert out.with_suffix(".md").exists()


def test_fit_participant_bad_input(tmp_path, capsys):
    err = cli_error(["fit-participant", str(tmp_path / "none"), "--out", "x.json"], capsys)
    assert "LOGS" in err
    (tmp_path / "empty").mkdir()
    err = cli_error(["fit-participant", str(tmp_path / "empty"), "--out", "x.json"], capsys)
    assert "no session logs" in err or "no" in err


@pytest.mark.parametrize("kind", ["strol", "e2e"])
def test_v2_ghat_trained_on_the_fitted_population(kind):
    """v2's study ĝ are its own, trained on the fitted population's corrections; v1's stay."""
    from strol_gym.learners.registry import make_learner

    for k in (1, 2, 3):
        learner = make_learner(kind, task=STUDY_TASKS_V2[k]())
        assert learner.checkpoint.endswith(f"study{k}-v2_{kind}.safetensors")
        training = learner.checkpoint_meta["training"]
        assert training["human"].endswith("population:FittedPopulationModel")
        assert training["sigma"] == 0.0
        # trained on the shipped population's own corrections
        assert training["human_kwargs"]["correction"] == population.SHIPPED_CORRECTION
    v1 = make_learner(kind, task=make_task("study-task1-v1"))
    assert v1.checkpoint.endswith(f"study1-v1_{kind}.safetensors")


def test_fitted_population_model_draws_the_fitted_sizes():
    """The training human's corrections have the population's sizes, unclipped."""
    task = STUDY_TASKS_V2[2]()
    model = population.FittedPopulationModel(task)
    n = 4000
    rng = np.random.default_rng(1)
    x = np.tile(task.start, (n, 1))
    u = model.correct(x, np.zeros((n, 6)), np.tile(task.theta_star, (n, 1)), rng)
    size = np.linalg.norm(u[:, :3], axis=1) / task.pos_step
    f = population.shipped().fitted
    assert abs(np.log(size).mean() - f["size_log_mean"]) < 0.05
    spread = math.sqrt(f["size_log_sd"] ** 2 + f["size_within"] ** 2)
    assert abs(np.log(size).std() - spread) < 0.05
    assert size.max() > 1.0  # past a_max: the run-time scale, not clipped
    with pytest.raises(ValueError, match="study Task"):
        population.FittedPopulationModel(make_task("robot"))


def test_fitted_population_model_reads_at_the_run_time_scale():
    """read_scale multiplies the position and the rotation parts separately (the same draws),
    and is checked."""
    task = STUDY_TASKS_V2[2]()
    n = 64
    x = np.tile(task.start, (n, 1))
    star = np.tile(task.theta_star, (n, 1))
    meant = population.FittedPopulationModel(task).correct(
        x, np.zeros((n, 6)), star, np.random.default_rng(3)
    )
    read = population.FittedPopulationModel(task, read_scale=(0.5, 2.0)).correct(
        x, np.zeros((n, 6)), star, np.random.default_rng(3)
    )
    np.testing.assert_allclose(read[:, :3], 0.5 * meant[:, :3], rtol=1e-12)
    np.testing.assert_allclose(read[:, 3:], 2.0 * meant[:, 3:], rtol=1e-12)
    for bad in ((0.0, 1.0), (1.0, -1.0), (1.0, 11.0), (1.0,), "11", (math.nan, 1.0)):
        with pytest.raises((ValueError, TypeError), match=r"read_scale"):
            population.FittedPopulationModel(task, read_scale=bad)


def test_best_correction_one_pose_is_a_batch_row():
    """θ*'s best correction at one pose and in a batch: the same bits (one contraction), as the
    participant and the ĝ training human use it."""
    task = STUDY_TASKS_V2[3]()
    rng = np.random.default_rng(5)
    x = task.sample_start(rng, 200)
    theta = rng.standard_normal((200, len(task.theta_star)))
    batch = population.best_correction(task, theta, x)
    rows = np.array([population.best_correction(task, theta[i], x[i]) for i in range(200)])
    assert batch.shape == (200, task.action_dim)
    assert np.array_equal(batch, rows)
    shared = population.best_correction(task, task.theta_star, x)  # one θ* for every pose
    assert np.array_equal(shared[7], population.best_correction(task, task.theta_star, x[7]))


def test_read_scale_is_the_median_read_over_the_median_meant():
    """participant_check's read scale: per part, the median read |u_H| over the median meant
    one, over every session's pushes (a push the arm lost counts as meant, not read)."""
    from lab.study.participant_check import read_scale

    sessions = [
        {"sizes": {"read": [(0.5, 0.2), (0.7, 0.4)], "intended": [(1.0, 0.4), (1.0, 0.4)]}},
        {"sizes": {"read": [(0.6, 0.3)], "intended": [(1.0, 0.6), (3.0, 0.2)]}},
    ]
    assert read_scale(sessions) == pytest.approx([0.6 / 1.0, 0.3 / 0.4])
    task1 = [{"sizes": {"read": [(0.5, 0.0)], "intended": [(1.0, 0.0)]}}]
    assert read_scale(task1) == pytest.approx([0.5, 1.0])  # no turns: rotation left at 1
    assert read_scale([{"sizes": {"read": [], "intended": []}}]) is None


def test_the_aimed_population_pushes_and_trains_with_one_model():
    """The shipped person's corrections and the ĝ training human's (``correction="aimed"``)
    are the aimed person's draws (``population.aimed_draws``); a bad model name is refused."""
    task = STUDY_TASKS_V2[2]()
    n = 8
    x = np.tile(task.start, (n, 1))
    star = np.tile(task.theta_star, (n, 1))
    model = population.FittedPopulationModel(task, read_scale=(0.5, 2.0), correction="aimed")
    u = model.correct(x, np.zeros((n, 6)), star, np.random.default_rng(4))
    draws = model.draw(np.random.default_rng(4), n)
    meant = population.aimed_draws(
        task, task.theta_star, x, draws.extra["z"][:, :7], draws.extra["pick"]
    )
    np.testing.assert_allclose(u[:, :3], 0.5 * meant[:, :3] * task.action_bound[:3])
    np.testing.assert_allclose(u[:, 3:], 2.0 * meant[:, 3:] * task.action_bound[3:])
    person = FittedParticipant(
        task, task.theta_star, np.random.default_rng(5), params=FittedParams(correction="aimed")
    )
    rng = np.random.default_rng(5)
    expect = population.aimed_draws(
        task, task.theta_star, task.start, rng.standard_normal((1, 7)), rng.random(1)
    )[0]
    np.testing.assert_allclose(person.act(task.start, np.zeros(6)), expect * task.action_bound)
    with pytest.raises(ValueError, match="correction must be one of"):
        population.FittedPopulationModel(task, correction="nope")
    with pytest.raises(ValueError, match=r"person kwargs\['correction'\]"):
        FittedParams(correction="nope")
