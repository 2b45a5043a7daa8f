"""Hardening, third round: inputs that gave NaN, numpy reprs, tracebacks or silently dropped
values now give a fix or one clear refusal (issue 31, items 2, 3, 7, 8)."""

from __future__ import annotations

import csv
import json
import warnings

import numpy as np
import pytest
from cli_checks import cli_error

from strol_gym import checks
from strol_gym.benchmarks.engine.config import paper_config
from strol_gym.benchmarks.engine.results import META, ResultsDir, ResultsError, write_csv
from strol_gym.files import MAX_JSON_DEPTH, loads_json
from strol_gym.humans import make_human
from strol_gym.learners import checkpoint as ckpt
from strol_gym.learners.registry import make_learner
from strol_gym.tasks import make_task

DEEP = "[" * 5000 + "]" * 5000
DEEPISH = '{"a": ' * (MAX_JSON_DEPTH + 1) + "1" + "}" * (MAX_JSON_DEPTH + 1)


# ---------------------------------------------------------------------- 2. CSV cells
def test_numpy_scalars_are_written_as_plain_numbers(tmp_path):
    rows = [{"a": np.float64(2.239766140212501), "b": np.int64(3), "c": np.bool_(True)}]
    path = write_csv(tmp_path / "t.csv", rows, ["a", "b", "c"])
    got = list(csv.reader(path.open()))[1]
    assert got == ["2.239766140212501", "3", "true"]
    assert float(got[0]) == 2.239766140212501  # round-trips exactly


# ---------------------------------------------------------------------- 3. bayes and NaN
@pytest.mark.parametrize("name", ["bayes", "bayes-teacher"])
def test_bayes_refuses_an_overflowing_update_and_stays_finite(name):
    task = make_task("highway")
    learner = make_learner(name, task, n_particles=64)
    x = np.zeros(task.state_dim)
    before = learner.theta.copy()
    with pytest.raises(ValueError, match="non-finite θ̂"):
        learner.update(x, np.full(task.action_dim, 1e308))
    np.testing.assert_array_equal(learner.theta, before)  # a refused update changes nothing
    after = learner.update(x, np.full(task.action_dim, 0.1))
    assert np.isfinite(after).all()


@pytest.mark.parametrize("name", ["gradient", "strol", "bayes", "bayes-teacher"])
def test_a_start_beyond_the_theta_range_is_refused(name):
    """reset(θ̂0 = 1e308) was accepted; bayes then refused every update blaming x and u_h."""
    task = make_task("highway")
    learner = make_learner(name, task)
    with pytest.raises(ValueError, match=r"^theta0 must be finite numbers in \[-1e\+06, 1e\+06\]"):
        learner.reset(np.full(task.dim, 1e308))
    assert np.isfinite(learner.reset(np.full(task.dim, 1e6))).all()  # the bound itself is a start


def test_bayes_teacher_batch_update_after_a_single_one():
    task = make_task("highway")
    learner = make_learner("bayes-teacher", task, n_particles=32)
    learner.update(np.zeros(task.state_dim), np.full(task.action_dim, 0.1))
    out = learner.update(np.zeros((4, task.state_dim)), np.full((4, task.action_dim), 0.1))
    assert out.shape == (4, task.dim) and np.isfinite(out).all()
    with pytest.raises(ValueError, match="batch sizes of x, u_h, u_r and theta disagree"):
        learner.update(np.zeros((3, task.state_dim)), np.full((3, task.action_dim), 0.1))


# ---------------------------------------------------------------------- 7. deep JSON, os:system
def test_deep_json_is_a_named_value_error():
    for text in (DEEP, DEEPISH):
        with pytest.raises(ValueError, match=rf"^--x: JSON nested deeper than {MAX_JSON_DEPTH}"):
            loads_json(text, "--x")
    assert loads_json('{"a": [1, {"b": 2}]}', "--x") == {"a": [1, {"b": 2}]}


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "--env", "robot", "--human-kwargs", DEEP],
        ["run", "--env", "robot", "--learner-kwargs", DEEP],
        ["train", "--task", "robot", "--human-kwargs", DEEP],
        ["run", "--env", "robot", "--condition", "os:system", "--runs", "1"],
        ["run", "--env", "robot", "--task", "os:system", "--runs", "1"],
        ["train", "--task", "os:system", "--steps", "1"],
        ["train", "--task", "robot", "--human", "os:system", "--steps", "1"],
    ],
    ids=[
        "run-human-kwargs",
        "run-learner-kwargs",
        "train-human-kwargs",
        "condition",
        "task",
        "train-task",
        "train-human",
    ],
)
def test_cli_refuses_deep_json_and_non_pieces_in_one_line(argv, tmp_path, capsys):
    out = ["--out", str(tmp_path / ("x.pt" if argv[0] == "train" else "res"))]
    line = cli_error([*argv, *out], capsys)
    assert "nested deeper" in line or "strol-gym can build" in line


def test_a_non_piece_is_an_argument_type_error_from_python():
    """``os:system`` as a Task or human: checks' one error (a TypeError and a ValueError)."""
    with pytest.raises(checks.ArgumentTypeError, match=r"^task 'os:system' is not a task"):
        make_task("os:system")
    with pytest.raises(checks.ArgumentTypeError, match=r"^human 'os:system' is not a human"):
        make_human("os:system", make_task("robot"), np.zeros(3), np.random.default_rng(0))


def test_deep_sidecar_is_named(tmp_path):
    pt = tmp_path / "w.pt"
    pt.write_bytes(b"")
    ckpt.sidecar_path(pt).write_text(DEEP)
    with pytest.raises(ValueError, match=r"checkpoint sidecar .*w\.json: JSON nested deeper"):
        ckpt.read_sidecar(pt)


# ---------------------------------------------------------------------- 7, 8. records and meta
def _folder(tmp_path):
    cfg = paper_config(["robot"], runs=2, learners=("gradient", "strol"), block=2)
    rd = ResultsDir.open(tmp_path / "r", cfg)
    for unit in cfg.units():
        exp = cfg.experiments[unit.experiment]
        recs = [
            {
                "env": exp.env,
                "condition": exp.condition.name,
                "learner": learner,
                "seed": s,
                "error": 0.5,
                "cos_error": 0.1,
                "regret": 0.2,
                "errors": [0.9, 0.5],
                "cos_errors": [0.3, 0.1],
                "steps": 2,
                "terminated": False,
            }
            for s in unit.seeds
            for learner in cfg.learners
        ]
        rd.write_unit(unit, recs)
    rd.finish_session("t", 1.0, 0, 1)
    return rd, cfg


def _edit_first_record(rd, cfg, edit):
    p = rd.record_path(cfg.units()[0])
    payload = json.loads(p.read_text())
    edit(payload)
    p.write_text(json.dumps(payload))
    return p


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d["records"][0].update(regret=float("nan")), r"'regret' is NaN while other"),
        (lambda d: d["records"][0].update(regret=float("inf")), r"'regret' must be a finite"),
        (lambda d: d["records"][0].update(regret=None), r"'regret' must be a finite"),
        (lambda d: d["records"][0]["errors"].append(float("inf")), r"'errors' must be a list"),
        (lambda d: d["records"][0].pop("errors"), r"'errors' is missing"),
        (lambda d: d["records"][0].update(steps=-3), r"'steps' must be an integer in \[0, 5\]"),
        (lambda d: d["records"][0].update(condition="clean"), r"is not its unit's"),
        (lambda d: d.update(records={"a": 1}), r"records must be a list of objects"),
    ],
    ids=["nan", "inf", "null", "inf-curve", "errors-missing", "steps", "condition", "records-dict"],
)
def test_hand_edited_records_are_named_not_dropped(tmp_path, edit, match):
    rd, cfg = _folder(tmp_path)
    assert len(ResultsDir.load(rd.path).read_records()) == 8 * 2
    p = _edit_first_record(rd, cfg, edit)
    with pytest.raises(ResultsError, match=rf"{p}.*{match}"):
        ResultsDir.load(rd.path).read_records()


def test_report_recomputes_the_config_hash(tmp_path, capsys):
    rd, _ = _folder(tmp_path)
    meta = json.loads((rd.path / META).read_text())
    meta["config"]["experiments"][0]["condition"]["sigma"] = 0.5  # hash kept
    (rd.path / META).write_text(json.dumps(meta))
    with pytest.raises(ResultsError, match="does not match its config_hash"):
        ResultsDir.load(rd.path)
    assert "does not match" in cli_error(["report", str(rd.path)], capsys)


def test_deep_meta_and_record_files_are_named(tmp_path):
    rd, cfg = _folder(tmp_path)
    p = rd.record_path(cfg.units()[0])
    p.write_text(DEEP)
    with pytest.raises(ResultsError, match=rf"{p} is corrupt .*nested deeper"):
        rd.read_records()
    (rd.path / META).write_text(DEEP)
    with pytest.raises(ResultsError, match="nested deeper"):
        ResultsDir.load(rd.path)


# ---------------------------------------------------------------------- 9. learner states
def _bayes_state(**edit):
    task = make_task("highway")
    learner = make_learner("bayes", task, n_particles=32)
    learner.update(np.zeros(task.state_dim), np.full(task.action_dim, 0.1))
    state = learner.state_dict()
    state.update(edit)
    return make_learner("bayes", task, n_particles=32), state


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        ({"beta_idx": np.full((1, 32), -1)}, r"beta_idx'\] must hold integers in \[0, "),
        ({"beta_idx": np.full((1, 32), 99)}, r"beta_idx'\] must hold integers"),
        ({"beta_idx": np.full((1, 32), 0.5)}, r"beta_idx'\] must hold integers"),
        ({"beta_idx": np.array([["a"] * 32])}, r"beta_idx'\] must hold integers"),
        ({"updates": -5}, r"updates'\] must be an integer >= 0"),
        ({"updates": 2.7}, r"updates'\] must be an integer >= 0"),
        ({"theta": np.zeros((4, 3))}, r"theta'\] \(4, 3\) does not match the posterior's 1 row"),
    ],
    ids=[
        "beta-neg",
        "beta-high",
        "beta-float",
        "beta-str",
        "updates-neg",
        "updates-float",
        "batches",
    ],
)
def test_bayes_state_is_checked_completely_and_changes_nothing(edit, match):
    learner, state = _bayes_state(**edit)
    before = learner.state_dict()
    with pytest.raises(ValueError, match=match):
        learner.load_state_dict(state)
    np.testing.assert_array_equal(learner.state_dict()["particles"], before["particles"])


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        ({"stat_sum": np.float64("nan")}, r"stat_sum'\] must be finite"),
        ({"stat_count": np.float64(-2)}, r"stat_count'\] must hold integers >= 0"),
        ({"stat_count": np.float64(1.5)}, r"stat_count'\] must hold integers >= 0"),
    ],
    ids=["sum-nan", "count-neg", "count-frac"],
)
def test_strol_adaptive_state_is_checked(edit, match):
    task = make_task("robot")
    learner = make_learner("strol-adaptive", task)
    state = {**learner.state_dict(), **edit}
    with pytest.raises(ValueError, match=match):
        make_learner("strol-adaptive", task).load_state_dict(state)


@pytest.mark.parametrize(
    ("cast", "match"),
    [("int64", "must be a torch.float32 tensor"), ("huge", r"holds a weight beyond ±1e\+06")],
)
def test_ghat_state_weights_are_checked_at_load(cast, match):
    import torch

    task = make_task("robot")
    learner = make_learner("strol", task)
    state = learner.state_dict()
    key = next(iter(state["model"]))
    w = state["model"][key]
    state["model"][key] = w.to(torch.int64) if cast == "int64" else torch.full_like(w, 1e30)
    with pytest.raises(ValueError, match=rf"state\['model'\]\['{key}'\] {match}"):
        make_learner("strol", task).load_state_dict(state)


# ---------------------------------------------------------------------- 10. sidecars
@pytest.mark.parametrize(
    ("edit", "match"),
    [
        ({"task": "robot"}, r"'task' must be an object"),
        ({"network": [1, 2]}, r"'network' must be an object"),
    ],
)
def test_sidecar_fields_of_the_wrong_kind_are_named(tmp_path, edit, match):
    pt = tmp_path / "w.safetensors"
    pt.write_bytes(b"")
    ckpt.sidecar_path(pt).write_text(json.dumps({"kind": "strol", **edit}))
    with pytest.raises(ValueError, match=rf"sidecar .*w\.json: {match}"):
        ckpt.read_sidecar(pt)


def test_fractional_hidden_widths_are_refused_not_truncated():
    from strol_gym.learners.network import CorrectionNet

    with pytest.raises(ValueError, match=r"hidden must be a non-empty list of positive integer"):
        CorrectionNet(4, 2, [256.5])


# ---------------------------------------------------------------------- 4. ray vs another service
def test_a_ray_address_where_another_service_listens_is_refused_at_once():
    import http.server
    import socket
    import threading
    import time

    from strol_gym.benchmarks.engine.backends import check_reachable

    http_server = http.server.HTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    silent = socket.create_server(("127.0.0.1", 0))  # accepts, never answers
    threading.Thread(target=http_server.serve_forever, daemon=True).start()
    try:
        t = time.monotonic()
        address = f"127.0.0.1:{http_server.server_address[1]}"
        with pytest.raises(ValueError, match=rf"--ray-address {address}: .* not a Ray cluster"):
            check_reachable(address)
        address = f"127.0.0.1:{silent.getsockname()[1]}"
        with pytest.raises(ValueError, match=rf"--ray-address {address}: no Ray cluster .*1 s"):
            check_reachable(address, timeout=1.0)
        assert time.monotonic() - t < 5
    finally:
        http_server.shutdown()
        http_server.server_close()
        silent.close()


# ---------------------------------------------------------------------- 12. leftovers, messages
def test_an_interrupted_train_does_not_promise_a_resume(monkeypatch, capsys):
    from strol_gym.benchmarks import cli

    def interrupted(args, parser):
        raise KeyboardInterrupt

    monkeypatch.setitem(cli.COMMANDS, "train", interrupted)
    assert cli.main(["train", "--task", "robot"]) == 130
    err = capsys.readouterr().err.strip()
    assert (
        err
        == "interrupted: nothing was saved (train keeps no partial state); rerun it to start over"
    )


def test_train_leaves_nothing_in_its_temporary_folder(tmp_path):
    """``train`` turns on torch's deterministic kernels, whose first use imports torch's
    compiler, which made ``$TMPDIR/torchinductor_<user>`` and left it (issue 31, item 12)."""
    import os
    import subprocess
    import sys

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "TORCHINDUCTOR_CACHE_DIR"}
    env["TMPDIR"] = str(tmp)
    out = tmp_path / "g.safetensors"
    args = ["train", "--steps", "1", "--batch", "4", "--heldout", "4", "--quiet", "--out", str(out)]
    cmd = [sys.executable, "-m", "strol_gym.benchmarks", *args]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert out.exists() and sorted(p.name for p in tmp.iterdir()) == []


def test_a_killed_writers_temp_files_are_cleaned_and_do_not_block_force(tmp_path):
    import subprocess
    import sys

    from strol_gym.benchmarks.engine.lock import host

    rd, cfg = _folder(tmp_path)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    left = [
        rd.path / f".meta.json.{host()}-{dead.pid}.x1.tmp",
        rd.path / "records" / f".{rd.record_path(cfg.units()[0]).name}.{host()}-{dead.pid}.x2.tmp",
    ]
    for p in left:
        p.write_text("{")
    ResultsDir.open(rd.path, cfg).finish_session("t", 1.0, 0, 1)  # resume: cleaned on open
    assert not any(p.exists() for p in left)
    left[0].write_text("{")
    other = rd.path / ".meta.json.node-17-1.x3.tmp"  # another host's: kept, and no obstacle
    other.write_text("{")
    ResultsDir.open(rd.path, cfg, force=True).finish_session("t", 1.0, 0, 1)
    assert not left[0].exists()


# ---------------------------------------------------------------------- 11. accepted silently
def test_replay_refuses_errors_that_overflow(tmp_path, capsys):
    import gymnasium as gym

    from strol_gym.benchmarks.sessions.replay import replay_session
    from strol_gym.wrappers import OnlineLearningWrapper
    from strol_gym.wrappers.session_log import SessionLogger, read_session

    log = tmp_path / "s.jsonl"
    env = SessionLogger(OnlineLearningWrapper(gym.make("StROL-Robot-v0"), "gradient"), log)
    env.reset(seed=0)
    env.step(np.zeros(3, dtype=np.float32))
    env.close()
    lines = [json.loads(x) for x in log.read_text().splitlines()]
    for rec in lines:
        if rec.get("type") == "episode":
            rec["theta_star"] = [1e308, -1e308]
    log.write_text("".join(json.dumps(r) + "\n" for r in lines))
    with pytest.raises(ValueError, match=rf"{log}: episode 0: ‖θ\* − θ̂‖ overflows"):
        replay_session(read_session(log), ["gradient"])
    assert "overflows" in cli_error(
        ["replay", str(log), "--learners", "gradient", "--no-plots"], capsys
    )


def test_basin_refuses_a_run_results_folder_as_out(tmp_path, capsys):
    rd, _ = _folder(tmp_path)
    line = cli_error(["basin", "--grid", "3", "--steps", "2", "--out", str(rd.path)], capsys)
    assert "is a benchmark's results folder" in line
    assert not (rd.path / "basin.csv").exists()


@pytest.mark.parametrize("env_id", ["StROL-Highway-v0", "StROL-Robot-v0"])
def test_theta_star_and_prior_modes_beyond_the_range_are_refused(env_id):
    import gymnasium as gym

    from strol_gym.priors import FixedPrior, MixturePrior

    env = gym.make(env_id)
    d = env.unwrapped.task.dim
    with pytest.raises(
        ValueError, match=r"^theta_star must be finite numbers in \[-1e\+06, 1e\+06\]"
    ):
        env.reset(seed=0, options={"theta_star": [1e308] * d})
    env.close()
    with pytest.raises(ValueError, match=r"^modes must be finite numbers in"):
        MixturePrior(np.full((2, d), 1e308))
    with pytest.raises(ValueError, match=r"^thetas must be finite numbers in"):
        FixedPrior(np.full((1, d), -1e300))


@pytest.mark.parametrize("value", [float("inf"), float("nan"), 0.0, -5.0])
def test_study_v1_reflex_thresholds_must_be_finite_and_positive(value):
    """Refused within the documented range (v1 and v2 share it: [20, 150] N)."""
    import gymnasium as gym

    with pytest.raises(ValueError, match=r"reflex_force must be a finite number in \[20, 150\]"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # v1 is deprecated
            gym.make("StROL-Study-v1", reflex_force=value)


@pytest.mark.parametrize("version", ["v1", "v2"])
@pytest.mark.parametrize(
    ("person", "named"),
    [
        ({"beta": 5.0}, "beta"),
        ({"kwargs": {"n_candidates": 8}}, "n_candidates"),
    ],
)
def test_study_participants_refuse_what_they_would_ignore(version, person, named):
    """v1's default participant ("observer") pushes θ*-greedy by itself, v2's ("fitted") from
    its fitted aim and sizes: a human model's parameter would be ignored, so it is refused,
    naming it."""
    import gymnasium as gym

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # v1 is deprecated
        with pytest.raises(ValueError, match=named):
            gym.make(f"StROL-Study-{version}", person=person)
        with pytest.raises(ValueError, match=named):
            gym.make(f"StROL-Study-{version}", person={"name": "observer", **person})


BOLTZMANN = {"name": "boltzmann", "beta": 5.0}


@pytest.mark.parametrize(
    ("env_id", "person", "user"),
    [
        ("StROL-Study-v0", BOLTZMANN, "BoltzmannHuman"),
        ("StROL-Study-v1", BOLTZMANN, "BoltzmannHuman"),
        ("StROL-Study-v2", BOLTZMANN, "BoltzmannHuman"),
        ("StROL-Study-v1", {}, "Participant"),  # the default still builds
        ("StROL-Study-v2", None, None),  # and so does no simulated person
    ],
)
def test_study_human_model_is_honoured_where_it_is_used(env_id, person, user):
    """Where the simulated user chooses its pushes from a human model, it is the one given."""
    import gymnasium as gym

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        env = gym.make(env_id, person=person)
    env.reset(seed=0)
    got = env.unwrapped.person
    if user == "BoltzmannHuman":
        assert type(got.model).__name__ == user and got.model.beta == 5.0
    else:
        assert (got if got is None else type(got).__name__) == user
    env.close()
