"""Bad arguments raise errors that name them, and inputs once accepted without a word are
refused: priors, actions, reset options and checkpoints from Python; complex numbers in every
learner; weights and states of absurd size; stray ``--learner-kwargs``; numbers beyond what a
dataset stores; a display that does not answer; temporary files left behind; a lock naming a
process that is not a run."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from cli_checks import cli_error

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.learners.checkpoint import load_checkpoint, rehash_sidecar, save_checkpoint
from strol_gym.learners.network import CorrectionNet
from strol_gym.learners.registry import list_learners, make_learner
from strol_gym.tasks import make_task

TASK = make_task("robot")


@pytest.mark.parametrize(
    "prior, words",
    [("builtins:eval", r"prior 'builtins:eval': its factory"), ([["a", "a"]], "prior must be")],
)
def test_a_bad_prior_is_named(prior, words):
    with pytest.raises(ValueError, match=words):
        gym.make("StROL-Robot-v0", prior=prior).reset(seed=0)


def test_ragged_actions_and_options_that_are_not_a_dict_are_named():
    env = gym.make("StROL-Robot-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action must be 3 numbers"):
        env.step([[0.1], [0.1, 0.2]])
    with pytest.raises(ValueError, match="options must be a dict"):
        env.reset(seed=0, options="x")


def test_a_checkpoint_that_is_not_a_path_or_not_a_weights_file_is_named(tmp_path):
    with pytest.raises(TypeError, match="checkpoint must be a path"):
        make_learner("strol", task=TASK, checkpoint=5)
    pt = tmp_path / "g.pt"
    save_checkpoint(
        pt, CorrectionNet(TASK.network_input_dim, TASK.dim, [8], "radial"), TASK, "strol"
    )
    renamed = pt.rename(tmp_path / "g.bin")
    pt.with_suffix(".json").rename(renamed.with_suffix(".json"))
    with pytest.raises(ValueError, match=r"checkpoint must be a \.safetensors \(or \.pt\) file"):
        make_learner("strol", task=TASK, checkpoint=str(renamed))


@pytest.mark.parametrize("bad", ["int64", "1e30"])
def test_weights_of_an_integer_type_or_absurd_size_are_refused_on_load(bad, tmp_path):
    """The sidecar's hash vouches for these bytes; the values themselves are checked."""
    path = tmp_path / "g.pt"
    net = CorrectionNet(TASK.network_input_dim, TASK.dim, [8], "radial")
    save_checkpoint(path, net, TASK, "strol")
    weights = {k: v.clone() for k, v in net.state_dict().items()}
    key = next(iter(weights))
    weights[key] = weights[key].to(torch.int64) if bad == "int64" else weights[key] + 1e30
    torch.save(weights, path)
    rehash_sidecar(path)
    words = "not floating point" if bad == "int64" else "beyond"
    with pytest.raises(ValueError, match=rf"weight '{key}' .*{words}"):
        load_checkpoint(path, TASK, "strol")


@pytest.mark.parametrize("name", ["bayes-teacher", "strol-unrolled", "gradient"])
def test_a_state_with_an_absurd_estimate_is_refused_on_load(name):
    learner = make_learner(name, task=TASK)
    learner.reset()
    state = learner.state_dict()
    state["theta"] = np.full(TASK.dim, 1e308)
    if "particles" in state:
        state["particles"] = np.full_like(state["particles"], 1e308)
    with pytest.raises(ValueError, match=r"state\['(theta|particles)'\] must be finite numbers in"):
        learner.load_state_dict(state)


def test_complex_inputs_are_refused_by_every_learner():
    x = np.full(TASK.state_dim, 0.1)
    u = np.full(TASK.action_dim, 0.1)
    for name in list_learners():
        learner = make_learner(name, task=TASK)
        learner.reset()
        for args in ((x + 1j, u), (x, u + 1j), (x, u, u + 1j)):
            with pytest.raises(TypeError, match="must be an array of real numbers"):
                learner.update(*args)


def test_learner_kwargs_for_a_learner_not_run_are_refused(tmp_path, capsys):
    log = tmp_path / "s.jsonl"
    log.write_text("{}\n")
    argv = ["replay", str(log), "--learners", "strol", "--learner-kwargs", '{"gradient": {}}']
    assert "'gradient', not among the learners run" in cli_error(argv, capsys)


def test_export_refuses_numbers_its_float32_data_would_store_as_inf():
    from strol_gym.benchmarks.sessions.export import _episode_buffer
    from strol_gym.wrappers.session_log import Episode

    pytest.importorskip("minari")
    step = {"x": np.zeros(3), "u_h": np.zeros(3), "u_r": np.zeros(3), "correction_time": None}
    ep = Episode(7, np.full(4, 1e308), None, [{**step, "theta_hat_after": np.zeros(4)}])
    with pytest.raises(ValueError, match="seed 7: theta_hat holds 1e\\+308, beyond the float32"):
        _episode_buffer(ep, {"s": 3, "a": 3, "d": 4}, 7)


def test_a_display_that_does_not_answer_is_refused(tmp_path, monkeypatch):
    pytest.importorskip("pygame")
    from strol_gym.benchmarks.sessions.drive import run_drive

    monkeypatch.setenv("DISPLAY", ":4242")  # no X server there
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.delenv("SDL_VIDEODRIVER", raising=False)
    with pytest.raises(ValueError, match="cannot open a window on DISPLAY=':4242'"):
        run_drive(log=tmp_path / "s.jsonl", duration=1.0)
    assert not (tmp_path / "s.jsonl").exists()


def test_the_sb3_example_keeps_its_temporary_files_in_a_folder_it_removes(tmp_path, monkeypatch):
    """stable-baselines3's logger folder and torch's compile cache go to ``gettempdir()``:
    inside the example's run that is a folder of its own, removed at the end."""
    import importlib.util
    import tempfile

    pytest.importorskip("stable_baselines3")
    script = Path(__file__).parents[1] / "benchmarks" / "examples" / "example_sb3.py"
    spec = importlib.util.spec_from_file_location("example_sb3_under_test", script)
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)
    with example.private_tmp():
        inside = Path(tempfile.gettempdir())
        assert inside.parent == tmp_path and os.environ["TMPDIR"] == str(inside)
        (inside / "SB3-2026-01-01").mkdir()  # what the logger makes
    assert list(tmp_path.iterdir()) == [] and os.environ["TMPDIR"] == str(tmp_path)


def test_a_lock_naming_a_process_that_is_not_a_run_is_gone():
    from strol_gym.benchmarks.engine.lock import Owner
    from strol_gym.files import host

    other = subprocess.Popen(["sleep", "30"])
    ours = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        for proc in (other, ours):  # until each has exec'd (its command line then reads)
            while not Path(f"/proc/{proc.pid}/cmdline").read_bytes():
                time.sleep(0.01)
        assert Owner.parse(str(other.pid)).gone()  # a bare pid: no start time to compare
        assert not Owner.parse(str(ours.pid)).gone()
        assert not Owner(host(), ours.pid, None, None).gone()
    finally:
        other.kill()
        ours.kill()
        other.wait()
        ours.wait()
