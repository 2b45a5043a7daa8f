"""When a person steps in: the timing hazard's likelihood and fit (``humans.timing``), the
reactive fitted participant, ``strol-bench fit-timing`` on synthetic sessions in the authors'
layout (written here, never their data) and ``strol-bench study --learners``."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from strol_gym.benchmarks import cli
from strol_gym.benchmarks.experiments import study as study_cmd
from strol_gym.benchmarks.sessions import fit_timing
from strol_gym.envs.study import population
from strol_gym.envs.study.participant import FittedParticipant
from strol_gym.envs.study.people import FittedParams
from strol_gym.humans import timing
from strol_gym.tasks.study import STUDY_TASKS_V2

DT = 0.05


def _simulate(coef: np.ndarray, n: int, seed: int) -> list[timing.TimedSession]:
    """Sessions of a person with the hazard ``coef`` and a learner that halves the shortfall
    at each correction (events by the discrete-time process the likelihood models)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        task = 1 + i % 3
        s, events, falls, last = rng.uniform(0.5, 2.0), [], [], 0
        falls.append(s)
        while True:  # the next event after ``last``: the first sample whose draw hits
            t = np.arange(last + (1 if events else 0), 800)
            eta = coef[task - 1] + coef[3] * s + coef[4] * np.log1p((t - last) * DT)
            hit = np.nonzero(rng.random(len(t)) < -np.expm1(-np.exp(eta) * DT))[0]
            if not len(hit):
                break
            last, s = int(t[hit[0]]), s * 0.5
            events.append(last)
            falls.append(s)
        out.append(timing.TimedSession(str(i % 10), task, "one", 800, np.array(events), falls))
    return out


def test_fit_recovers_a_reactive_hazard_and_beats_the_rate():
    truth = np.array([-3.0, -2.6, -2.8, 1.2, 0.3])
    sessions = _simulate(truth, 240, seed=3)
    f = timing.fit(sessions, "reactive", DT)
    assert f.coef[3] == pytest.approx(truth[3], abs=0.35)
    assert f.coef[4] == pytest.approx(truth[4], abs=0.2)
    rate = timing.fit(sessions, "rate", DT)
    assert f.loglik > timing.fit(sessions, "wait", DT).loglik > rate.loglik - 1e-9
    assert rate.coef[3] == rate.coef[4] == 0.0
    # a held-out set: the true model beats the learner-independent one
    test = _simulate(truth, 60, seed=4)
    assert timing.loglik(f, test) > timing.loglik(rate, test)


def test_fitted_counts_match_the_real_counts_in_sample():
    """At the maximum the expected count along the fitted paths equals the real one per Task
    (the score equation of each Task's intercept)."""
    sessions = _simulate(np.array([-3.0, -2.6, -2.8, 1.2, 0.3]), 60, seed=5)
    for model in timing.MODELS:
        f = timing.fit(sessions, model, DT)
        pred = timing.predicted_counts(f, sessions)
        for task in (1, 2, 3):
            rows = [i for i, s in enumerate(sessions) if s.task == task]
            real = sum(len(sessions[i].events) for i in rows)
            assert pred[rows].sum() == pytest.approx(real, rel=1e-6)


def test_a_timed_session_is_checked():
    with pytest.raises(ValueError, match="events must be sorted path samples"):
        timing.TimedSession("1", 1, "one", 10, np.array([3, 12]), [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="shortfall must hold 2"):
        timing.TimedSession("1", 1, "one", 10, np.array([3]), [0.0])
    with pytest.raises(ValueError, match="task must be one of"):
        timing.TimedSession("1", 4, "one", 10, np.array([], dtype=int), [0.0])
    with pytest.raises(ValueError, match="model must be one of"):
        timing.fit([], "nope")


def test_the_shipped_population_reacts_and_its_hazard_is_checked():
    pop = population.shipped()
    shipped = json.loads(population.TIMING_FILE.read_text())
    assert shipped["format"] == population.TIMING_FORMAT and shipped["fit_learners"]
    for t in (1, 2, 3):
        person = pop.draw(np.random.default_rng(t), t)
        assert person.hazard == tuple(shipped["hazard"][str(t)])
        if str(t) in shipped.get("doubled_budget", {}):  # the authors' doubled count ends it
            assert person.path_time == np.inf
            assert person.doubled_budget == shipped["doubled_budget"][str(t)]
        else:
            assert person.path_time == shipped["path_time"][str(t)]
            assert person.doubled_budget == np.inf
        assert person.ramp == shipped["rise"]  # the push rises as the real pushes logged
    with pytest.raises(ValueError, match=r"person kwargs\['hazard'\]"):
        FittedParams(hazard=(0.0, 1.0))
    with pytest.raises(ValueError, match=r"person kwargs\['path_time'\]"):
        FittedParams(path_time=0.0)
    with pytest.raises(ValueError, match=r"person kwargs\['doubled_budget'\]"):
        FittedParams(doubled_budget=-1.0)
    with pytest.raises(ValueError, match=r"doubled_budget.*'4'"):
        population.parse_doubled({"doubled_budget": {"4": 60.0}})
    assert population.parse_doubled({}) == {}


def test_impatience_weighs_the_wait_by_the_shortfall():
    """rate = exp(a + b s + (c + d s) log(1 + τ)); without d the reactive form, bit for bit."""
    a, b, c, d = -3.0, 0.5, 0.2, 0.7
    want = math.exp(a + b * 0.4 + (c + d * 0.4) * math.log1p(9.0))
    assert timing.hazard_rate((a, b, c, d), 0.4, 9.0) == pytest.approx(want)
    assert timing.rate(np.array([a, 0.0, 0.0, b, c, d]), 1, 0.4, 9.0) == pytest.approx(want)
    three = math.exp(min(a + b * 0.4 + c * math.log1p(9.0), 50.0))
    assert timing.hazard_rate((a, b, c), 0.4, 9.0) == three
    with pytest.raises(ValueError, match="3 or 4 numbers"):
        timing.hazard_vector("h", [1.0, 2.0])
    assert timing.MODELS["impatient"] == ("shortfall", "wait", "impatience")


def test_doubled_end_stops_where_the_authors_task_1_loop_did():
    """Elapsed = motion + the motion before the last correction: the session ends at budget −
    t_last, or at a correction once 2·t_k reaches the budget; later corrections are not made."""
    ends = timing.doubled_end
    got, n = ends(np.array([100, 300]), 1000)
    assert got.tolist() == [100, 300] and n == 700
    got, n = ends(np.array([100, 950]), 1000)  # 950 + 100 ≥ 1000: over before the second
    assert got.tolist() == [100] and n == 900
    got, n = ends(np.array([600, 700]), 1000)  # 2 × 600 ≥ 1000: over at the first
    assert got.tolist() == [600] and n == 601
    got, n = ends(np.array([], dtype=np.int64), 1000)
    assert got.tolist() == [] and n == 1000
    with pytest.raises(ValueError, match="timing fit"):
        population.parse_timing({"format": "other"})


def _judgments(hazard, path_time=1e9, steps=200, doubled=np.inf, watched=0.0):
    task = STUDY_TASKS_V2[1]()
    params = FittedParams(hazard=hazard, path_time=path_time, reaction=0.0, doubled_budget=doubled)
    p = FittedParticipant(task, task.theta_star, np.random.default_rng(0), params=params)
    p._shortfalls[task.theta_star.tobytes()] = 0.0  # the robot's plan: the person's own
    p._watched_last = watched  # the robot's motion before its last push
    pushes = [
        t for t in np.arange(steps) * 0.5 if p._decide(t, task.start, task.theta_star) is not None
    ]
    return p, pushes


def test_a_reactive_participant_steps_in_by_its_hazard():
    p, pushes = _judgments((5.0, 0.0, 0.0))  # rate e^5 per s: it steps in at once
    assert p.needs_theta_hat and pushes and pushes[0] == p.params.rest  # reaction 0
    p, pushes = _judgments((-40.0, 0.0, 0.0))  # never
    assert pushes == [] and p.judgments > 100
    p, pushes = _judgments((-40.0, 0.0, 0.0), path_time=10.0)  # done after 10 s watched
    assert p.done_at == pytest.approx(10.0)
    p, pushes = _judgments((-40.0, 0.0, 0.0), doubled=10.0, watched=4.0)  # 6 s + 4 s twice
    assert p.done_at == pytest.approx(6.0)
    with pytest.raises(ValueError, match="needs the robot's theta_hat"):
        p.shortfall(None)


@pytest.fixture(scope="module")
def timing_logs(authors_tree, tmp_path_factory):
    """Four people × 3 Tasks × One, MOF, StROL, imported with θ̂ reconstructed."""
    root = authors_tree(people=4, seed=11, scale=0.05, turn=(1.0, 0.0, 0.0))
    out = tmp_path_factory.mktemp("logs") / "logs"
    assert cli.main(["import-study", str(root), "--out", str(out), "--theta0", "implied"]) == 0
    return out


def test_fit_timing_on_synthetic_sessions(timing_logs, tmp_path, capsys):
    fit_file = tmp_path / "timing_fit.json"
    argv = ["fit-timing", str(timing_logs), "--out", str(tmp_path), "--bootstrap", "3"]
    assert cli.main([*argv, "--write-fit", str(fit_file)]) == 0
    assert "held out strol (0 sessions)" in capsys.readouterr().out  # StROL's θ̂ unknown here
    res = json.loads((tmp_path / "timing.json").read_text())
    assert res["sessions"]["fit"] == 24 and len(res["skipped"]) == 12
    assert set(res["models"]) == set(timing.MODELS)
    assert res["lopo_loglik"]["rate"] < 0
    hazard, path_time, rise = population.parse_timing(json.loads(fit_file.read_text()))
    assert path_time[1] == pytest.approx(40 * DT) and set(hazard) == {1, 2, 3}
    assert all(len(h) == 4 for h in hazard.values())  # a, b, c and the impatience d
    assert rise == pytest.approx(2 * DT)  # poses per correction 5, 0, 1, 3: median 2
    doubled = population.parse_doubled(json.loads(fit_file.read_text()))
    assert set(doubled) == {1} and doubled[1] >= path_time[1]  # the path and its last push
    # --ship reactive --no-doubled-end: the three-number hazard, no doubled end
    old = fit_timing.population_fit(res, {1: [40], 2: [40], 3: [40]}, "reactive", False)
    assert all(len(h) == 3 for h in old["hazard"].values()) and "doubled_budget" not in old
    with pytest.raises(SystemExit):
        cli.main(["fit-timing", str(timing_logs), "--out", str(tmp_path), "--bootstrap", "0"])


def test_study_with_learners_without_strol_says_h3_was_not_evaluated(tmp_path, capsys):
    out = tmp_path / "study"
    argv = ["study", "--task", "1", "--users", "1", "--jobs", "1", "--out", str(out), "--quiet"]
    assert cli.main([*argv, "--env-version", "v0", "--learners", "one,gradient"]) == 0
    assert "H3 was not evaluated" in capsys.readouterr().out
    rows = list(csv.DictReader(open(out / "study_table.csv")))
    assert {r["learner"] for r in rows} == {"one", "gradient"}
    assert all(math.isfinite(float(r["all_mean"])) for r in rows if r["metric"] == "corrections")
    study = json.loads((out / "study.json").read_text())
    assert study["h3_evaluated"] is False and study["verdicts"] == []
    with pytest.raises(SystemExit) as e:
        cli.main([*argv, "--learners", "one,nope"])
    assert e.value.code == 2


def test_study_tests_h3_for_the_reference_learner(tmp_path, capsys):
    """--reference: H3 tests that learner against One and MOF, the tables say which; a name
    not run is refused naming the flag, and One or MOF cannot be tested against itself."""
    out = tmp_path / "study"
    argv = ["study", "--task", "1", "--users", "2", "--jobs", "1", "--quiet", "--no-plots"]
    argv += ["--env-version", "v0", "--learners", "one,mof,gradient"]
    assert cli.main([*argv, "--out", str(out), "--reference", "gradient"]) == 0
    text = capsys.readouterr().out
    assert "H3 verdicts (Gradient vs One and MOF" in text
    assert "ANOVA over One, MOF and Gradient" in text
    study = json.loads((out / "study.json").read_text())
    assert study["h3_evaluated"] is True and [v["task"] for v in study["verdicts"]] == [1]
    assert {tuple(p["means"]) for p in study["pooled"]} == {("one", "mof", "gradient")}
    with pytest.raises(SystemExit) as e:
        cli.main([*argv, "--out", str(tmp_path / "b"), "--reference", "strol"])
    assert e.value.code == 2 and "--reference must be one of" in capsys.readouterr().err
    config = study_cmd.study_config
    learners = ("one", "mof", "gradient")
    assert not study_cmd.h3_evaluable(config((1,), 2, learners=learners, reference="one"))
    assert not study_cmd.h3_evaluable(config((1,), 2, learners=learners))  # no strol


def test_simulate_draws_the_process_the_likelihood_scores():
    """A constant hazard's mean count is samples × P(step in per sample); a plan whose
    shortfall falls at a logged switch lowers the rate after it; same seed, same events."""
    rng = np.random.default_rng(8)
    hazard, n = (-2.0, 1.5, 0.0), 800
    p = timing.step_in_probability(math.exp(-2.0), DT)
    counts = [len(timing.simulate(hazard, n, np.array([]), [0.0], DT, rng)) for _ in range(300)]
    assert np.mean(counts) == pytest.approx(n * p, rel=0.1)
    falls = [
        len(timing.simulate(hazard, n, np.array([400]), [1.0, 0.0], DT, rng)) for _ in range(300)
    ]
    assert np.mean(falls) == pytest.approx(400 * p * (math.exp(1.5) + 1), rel=0.1)
    a = timing.simulate(hazard, n, np.array([400]), [1.0, 0.0], DT, np.random.default_rng(1))
    b = timing.simulate(hazard, n, np.array([400]), [1.0, 0.0], DT, np.random.default_rng(1))
    assert np.array_equal(a, b)
