"""A session through Minari and back: strol-bench export, minari.load_dataset, and replay of
the dataset gives the θ̂ of replaying the log, to the bit."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.benchmarks.cli import main
from strol_gym.benchmarks.sessions.export import read_any
from strol_gym.benchmarks.sessions.replay import replay_session
from strol_gym.wrappers import OnlineLearningWrapper
from strol_gym.wrappers.session_log import SessionLogger, read_session

minari = pytest.importorskip("minari", reason='Minari is not installed (pip install ".[data]")')

DATASET = "strol/robot-session-v0"


def cli(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code)


@pytest.fixture
def log(tmp_path, monkeypatch):
    """Two Robot episodes of StROL under noisy corrections, logged; Minari writes into tmp."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    return robot_session(tmp_path / "s.jsonl")


def robot_session(path):
    """Log two Robot episodes (seeds 3, 4) of StROL under noisy corrections into ``path``."""
    env = SessionLogger(
        OnlineLearningWrapper(
            gym.make("StROL-Robot-v0", person={"sigma": 0.25, "bias": 0.1}), "strol"
        ),
        path,
    )
    task = env.unwrapped.task
    for seed in (3, 4):
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            u_r = task.robot_policy(obs["state"], obs["theta_hat"])[0]
            obs, _, terminated, truncated, _ = env.step(u_r / task.robot_action_bound)
            done = terminated or truncated
    env.close()
    return path


def test_session_round_trips_through_minari(log, tmp_path, capsys):
    assert cli(["export", DATASET, "--log", str(log)]) == 0
    assert str(tmp_path / "minari") in capsys.readouterr().out
    session = read_session(log)
    dataset = minari.load_dataset(DATASET)
    assert dataset.total_episodes == 2
    assert dataset.total_steps == session.n_corrections > 0
    for ep, logged in zip(dataset.iterate_episodes(), session.episodes, strict=True):
        assert ep.observations["state"].dtype == np.float32
        assert ep.actions.dtype == np.float32 and len(ep.actions) == len(logged.corrections)
        x = np.array([c["x"] for c in logged.corrections])
        assert ep.infos["x"].dtype == np.float64
        np.testing.assert_array_equal(ep.infos["x"][:-1], x)  # exact, not float32
        np.testing.assert_array_equal(ep.infos["u_h"][:-1], [c["u_h"] for c in logged.corrections])
        np.testing.assert_array_equal(ep.infos["theta_star"][0], logged.theta_star)

    # Replaying the dataset and the log gives the same θ̂ after every correction.
    learners = ["strol", "gradient"]
    from_log = replay_session(session, learners)
    from_data = replay_session(read_any(DATASET), learners)
    for name in learners:
        for a, b in zip(from_log[name], from_data[name], strict=True):
            np.testing.assert_array_equal(a, b)
    # ... and the logged learner's replay is the session's own θ̂.
    for curve, ep in zip(from_data["strol"], session.episodes, strict=True):
        np.testing.assert_array_equal(curve[1:], [c["theta_hat_after"] for c in ep.corrections])

    out = tmp_path / "replayed"
    assert cli(["replay", DATASET, "--learners", "strol", "--no-plots", "--out", str(out)]) == 0
    assert (out / "replay.csv").is_file()
    assert cli(["export", DATASET, "--log", str(log)]) == 2  # never overwrites a dataset
    assert "already exists" in capsys.readouterr().err


def test_dataset_header_is_checked_like_a_log(log, capsys):
    """A dataset whose header names code is refused as a log would be."""
    assert cli(["export", DATASET, "--log", str(log)]) == 0
    dataset = minari.load_dataset(DATASET)
    header = json.loads(dataset.storage.metadata["strol_session_header"])
    dataset.storage.update_metadata(
        {"strol_session_header": json.dumps({**header, "task": "os:abort"})}
    )
    assert cli(["replay", DATASET, "--learners", "gradient", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "os:abort" in err and "--plugin os" in err
    assert cli(["replay", "strol/no-such-v0", "--learners", "gradient"]) == 2
    assert "neither a session log" in capsys.readouterr().err


def test_benchmark_runs_as_a_dataset(tmp_path, monkeypatch, capsys):
    """strol-bench export --env: the runs strol-bench run plays (same seeds, so the same θ*)."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    argv = ["export", "strol/robot-runs-v0", "--env", "robot", "--learner", "gradient"]
    assert cli([*argv, "--condition", "noisy-biased", "--runs", "2", "--seed", "7"]) == 0
    dataset = minari.load_dataset("strol/robot-runs-v0")
    assert dataset.total_episodes == 2
    session = read_any("strol/robot-runs-v0")
    assert session.header["extra"]["benchmark"]["condition"]["name"] == "noisy-biased"
    for ep, seed in zip(session.episodes, (7, 8), strict=True):
        env = gym.make("StROL-Robot-v0", person={"sigma": 0.5, "bias": 0.5})
        _, info = env.reset(seed=seed)
        env.close()
        np.testing.assert_array_equal(ep.theta_star, info["theta_star"])
    replayed = replay_session(session, ["gradient"])["gradient"]
    for curve, ep in zip(replayed, session.episodes, strict=True):
        np.testing.assert_array_equal(curve[1:], [c["theta_hat_after"] for c in ep.corrections])
