"""Regression tests for the second hardening probe: every crash a clear error, every size
bounded, every file checked.

Each test failed before its fix. Command-line errors: exit status 2 and one line naming the
argument (and its range) or the file, no traceback. No test allocates anything large: bounds are
checked by the error raised before any allocation.
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from cli_checks import cli_error

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.analysis import basin_map
from strol_gym.benchmarks import cli
from strol_gym.benchmarks.args import BASIN_CAPS, RUN_CAPS, TRAIN_CAPS
from strol_gym.benchmarks.engine import pool as engine_pool
from strol_gym.benchmarks.engine import results
from strol_gym.benchmarks.engine.config import BenchConfig, Experiment
from strol_gym.benchmarks.engine.results import LOCK, META, ResultsDir, ResultsError
from strol_gym.benchmarks.train import add_train_arguments, run_train
from strol_gym.learners import checkpoint as ckpt
from strol_gym.learners.network import CorrectionNet
from strol_gym.learners.registry import list_learners, make_learner
from strol_gym.tasks.robot import RobotTask
from strol_gym.wrappers import OnlineLearningWrapper

ROBOT = RobotTask()
CLI = Path(sys.executable).with_name("strol-bench")
BOOM = '''
import os

from strol_gym import register_learner
from strol_gym.learners.rules import GradientLearner


class Boom(GradientLearner):
    """Gradient, but its direction() raises while STROL_TEST_BOOM is set."""

    def direction(self, x, u_h, u_r, theta):
        if os.environ.get("STROL_TEST_BOOM"):
            raise RuntimeError("boom inside direction()\\nsecond line")
        return super().direction(x, u_h, u_r, theta)


register_learner("boom", Boom)
'''


def _one_error_line(proc: subprocess.CompletedProcess) -> str:
    """Status 2, no traceback, exactly one error line on stderr; returns it."""
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if "error" in ln.lower()]
    assert len(lines) == 1, proc.stderr
    return lines[0]


def _cli(args, cwd=None, env=None, timeout=240, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(CLI), *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        **kw,
    )


# ---------------------------------------------------------------------- 1. a learner that raises
@pytest.mark.parametrize("jobs", ["1", "2"])
def test_a_learner_raising_mid_run_is_named_with_its_run_seed_and_the_folder_resumes(
    tmp_path, jobs
):
    (tmp_path / "boom.py").write_text(textwrap.dedent(BOOM))
    out = tmp_path / "res"
    args = [
        "run",
        *("--env", "robot", "--plugin", "boom.py", "--learners", "gradient,boom"),
        *("--runs", "2", "--corrections", "2", "--block", "1", "--jobs", jobs),
        *("--quiet", "--no-plots", "--out", str(out)),
    ]
    env = {**os.environ, "STROL_TEST_BOOM": "1"}
    line = _one_error_line(_cli(args, cwd=tmp_path, env=env))
    assert "learner 'boom' failed in run seed" in line
    assert "robot" in line and "RuntimeError: boom inside direction() second line" in line
    assert json.loads((out / META).read_text())["status"] == "incomplete"
    assert not (out / LOCK).exists()  # the folder is released for the rerun
    if jobs == "2":
        return  # resuming is the same with either --jobs: checked once
    del env["STROL_TEST_BOOM"]
    again = _cli(args, cwd=tmp_path, env=env)  # the same command resumes; no --force needed
    assert again.returncode == 0, again.stderr
    assert (out / "runs.csv").is_file()


def _session_log(path: Path) -> Path:
    from strol_gym.wrappers.session_log import SessionLogger

    env = SessionLogger(OnlineLearningWrapper(gym.make("StROL-Robot-v0"), "gradient"), path)
    env.reset(seed=0)
    for _ in range(2):
        env.step(np.zeros(3, dtype=np.float32))
    env.close()
    return path


def test_replay_names_a_learner_that_raises_with_episode_and_correction(tmp_path):
    (tmp_path / "boom.py").write_text(textwrap.dedent(BOOM))
    log = _session_log(tmp_path / "s.jsonl")
    args = ["replay", str(log), "--learners", "boom", "--plugin", "boom.py", "--no-plots"]
    proc = _cli(args, cwd=tmp_path, env={**os.environ, "STROL_TEST_BOOM": "1"})
    line = _one_error_line(proc)
    assert "learner 'boom' failed in episode 0, correction 0" in line and str(log) in line


# ---------------------------------------------------------------------- 2. train's output
def test_train_refuses_an_unwritable_out_before_any_work(capsys):
    t0 = time.perf_counter()
    line = cli_error(["train", "--out", "/proc/x.pt", "--steps", "500"], capsys)
    assert "--out /proc/x.pt" in line and "cannot write in /proc" in line
    assert time.perf_counter() - t0 < 30  # refused before training (500 steps take longer)


AS_NOBODY = """
import os, sys
# Everything the command needs is imported as root first: here the interpreter and its library
# live in root's private home, which uid 65534 cannot read; then the process drops to 65534.
import tempfile
from strol_gym.benchmarks import cli
from strol_gym.learners import training
cli.build_parser()  # its lazy imports too
os.setgid(65534)
os.setuid(65534)
assert os.geteuid() == 65534
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to drop to uid 65534")
def test_train_refuses_out_in_a_folder_the_user_cannot_write():
    """As root every folder is writable; run the command as nobody (uid 65534) instead."""
    folder = Path(tempfile.mkdtemp(prefix="strol-ro-"))  # root's 0700 tmp_path is not visible
    try:
        folder.chmod(0o755)
        proc = subprocess.run(
            [sys.executable, "-c", AS_NOBODY, "train", "--out", str(folder / "w.pt")],
            cwd="/",
            capture_output=True,
            text=True,
            timeout=240,
        )
        line = _one_error_line(proc)
        assert str(folder / "w.pt") in line and "ermission denied" in line
        assert list(folder.iterdir()) == []
    finally:
        shutil.rmtree(folder)


def test_a_failed_save_leaves_neither_a_partial_pt_nor_temporaries(tmp_path, monkeypatch):
    model = CorrectionNet(ckpt.input_dim(ROBOT, "strol"), ROBOT.dim, (4,))

    def full_disk(obj, f):
        Path(f).write_bytes(b"PK partial")
        raise RuntimeError("[Errno 28] No space left on device")

    monkeypatch.setattr(ckpt.torch, "save", full_disk)
    with pytest.raises(OSError, match=rf"cannot write {tmp_path / 'w.pt'}: .*No space left"):
        ckpt.save_checkpoint(tmp_path / "w.pt", model, ROBOT, "strol")
    assert list(tmp_path.iterdir()) == []


def test_save_writes_weights_and_sidecar_together(tmp_path):
    model = CorrectionNet(ckpt.input_dim(ROBOT, "strol"), ROBOT.dim, (4,))
    path = ckpt.save_checkpoint(tmp_path / "w.pt", model, ROBOT, "strol")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.json", "w.pt"]
    loaded, meta = ckpt.load_checkpoint(path, ROBOT, "strol")
    assert meta["weights_sha256"] == ckpt.weights_sha256(path)
    assert loaded.hidden == (4,)


# ---------------------------------------------------------------------- 3. size caps
@pytest.mark.parametrize(
    ("argv", "flag", "cap"),
    [
        (["train", "--batch", "100000000"], "--batch", TRAIN_CAPS["batch"]),
        (["train", "--steps", "100000000"], "--steps", TRAIN_CAPS["steps"]),
        (["train", "--candidates", "100000000"], "--candidates", TRAIN_CAPS["candidates"]),
        (["train", "--heldout", "100000000"], "--heldout", TRAIN_CAPS["heldout"]),
        (["train", "-K", "100000000"], "--unroll", TRAIN_CAPS["unroll"]),
        (["basin", "--grid", "100000"], "--grid", BASIN_CAPS["grid"]),
        (["basin", "--steps", "100000000"], "--steps", BASIN_CAPS["steps"]),
        (
            ["run", "--env", "robot", "--corrections", "100000000", "--runs", "1"],
            "--corrections",
            RUN_CAPS["corrections"],
        ),
    ],
)
def test_sizes_above_their_fixed_cap_are_refused_at_once(argv, flag, cap, capsys, tmp_path):
    t0 = time.perf_counter()
    line = cli_error([*argv, "--out", str(tmp_path / "x.pt")], capsys)
    assert f"{flag} must be at most {cap:,}" in line and "--allow-large" in line
    assert time.perf_counter() - t0 < 30
    assert list(tmp_path.iterdir()) == []


def test_allow_large_lifts_the_caps():
    from strol_gym.benchmarks.args import check_size_caps

    args = cli.build_parser().parse_args(["basin", "--grid", "1000", "--allow-large"])
    check_size_caps(args, BASIN_CAPS)  # no error: lifted
    args.allow_large = False
    with pytest.raises(ValueError, match="--grid must be at most 201"):
        check_size_caps(args, BASIN_CAPS)


# ---------------------------------------------------------------------- 4. sidecar vs weights
def test_an_edited_sidecar_cannot_make_loading_build_a_large_network(tmp_path, monkeypatch):
    src = ckpt.find_pretrained(ROBOT, "strol")
    shutil.copy(src, tmp_path / "w.safetensors")
    meta = json.loads(src.with_suffix(".json").read_text())
    meta["network"]["hidden"] = [300_000]  # the probe used 10⁹; small enough to be harmless here
    (tmp_path / "w.json").write_text(json.dumps(meta))
    real = ckpt.CorrectionNet

    def only_on_meta(*args, **kwargs):
        assert torch.empty(0).device.type == "meta", "a real network was built before the check"
        return real(*args, **kwargs)

    monkeypatch.setattr(ckpt, "CorrectionNet", only_on_meta)
    with pytest.raises(ValueError, match=r"sidecar's network does not match the weights.*300000"):
        ckpt.load_checkpoint(tmp_path / "w.safetensors", ROBOT, "strol")
    with pytest.raises(ValueError, match="does not match the weights"):
        make_learner("strol", task=ROBOT, checkpoint=tmp_path / "w.safetensors")


# ---------------------------------------------------------------------- 5. learner state
def _learners() -> list:
    return [make_learner(name, task=ROBOT) for name in list_learners()]


@pytest.mark.parametrize("name", list_learners())
def test_load_state_dict_none_is_a_type_error_for_every_learner(name):
    learner = make_learner(name, task=ROBOT)
    with pytest.raises(TypeError, match="load_state_dict needs the dict from state_dict"):
        learner.load_state_dict(None)


@pytest.mark.parametrize("name", list_learners())
def test_nan_or_missing_theta_is_refused_and_theta_hat_unchanged(name):
    learner = make_learner(name, task=ROBOT)
    learner.update(ROBOT.start, np.array([0.05, -0.05, 0.0]))
    before = np.array(learner.theta)
    state = learner.state_dict()
    for bad in ({**state, "theta": np.full_like(before, np.nan)}, {**state, "theta": None}):
        with pytest.raises(ValueError, match="theta"):
            learner.load_state_dict(bad)
        np.testing.assert_array_equal(learner.theta, before)
    missing = {k: v for k, v in state.items() if k != "theta"}
    with pytest.raises(ValueError, match="theta"):
        learner.load_state_dict(missing)
    np.testing.assert_array_equal(learner.theta, before)


@pytest.mark.parametrize("name", ["bayes", "bayes-teacher"])
@pytest.mark.parametrize("key", ["particles", "logw"])
def test_bayes_refuses_a_nan_posterior(name, key):
    learner = make_learner(name, task=ROBOT, n_particles=50)
    learner.update(ROBOT.start, np.array([0.05, -0.05, 0.0]))
    before = np.array(learner.theta)
    state = learner.state_dict()
    bad = np.array(state[key], dtype=np.float64)
    bad.flat[0] = np.nan
    with pytest.raises(ValueError, match=rf"state\['{key}'\] must be finite"):
        learner.load_state_dict({**state, key: bad})
    np.testing.assert_array_equal(learner.theta, before)
    with pytest.raises(ValueError, match=r"must match logw|must be logw's shape"):
        learner.load_state_dict({**state, key: np.array(state[key])[:-1]})
    np.testing.assert_array_equal(learner.theta, before)


# ---------------------------------------------------------------------- 6. basin's θ*
def test_basin_refuses_a_theta_star_whose_errors_overflow(capsys, tmp_path):
    argv = ["basin", "--theta-star", "1e308,1e308", "--grid", "3", "--steps", "2"]
    line = cli_error([*argv, "--out", str(tmp_path / "b"), "--no-plots"], capsys)
    assert "theta_star must be finite numbers in [-1e+06, 1e+06]" in line
    assert not (tmp_path / "b").exists()
    m = basin_map(ROBOT, "gradient", 3, theta_star=[1e6, -1e6], steps=1)
    assert np.isfinite(m.error).all()


# ---------------------------------------------------------------------- 7. errors name the file
def _tiny_config() -> BenchConfig:
    from strol_gym.benchmarks.engine.conditions import make_condition

    exp = Experiment("robot", make_condition("robot", "training"), runs=1, n_corrections=1)
    return BenchConfig((exp,), ("gradient",), "gradient", 1)


def test_a_binary_record_is_named(tmp_path, capsys):
    rd = ResultsDir.open(tmp_path / "r", _tiny_config())
    unit = rd.config.units()[0]
    rd.record_path(unit).write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(ResultsError, match=str(rd.record_path(unit)) + r" is corrupt"):
        rd.read_records()
    rd.finish_session("t", 1.0, 0, 1)
    assert str(rd.record_path(unit)) in cli_error(["report", str(tmp_path / "r")], capsys)


def test_a_full_disk_names_the_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    def no_space(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(results.os, "fsync", no_space)
    with pytest.raises(OSError, match="No space left") as e:
        results.write_json_atomic(tmp_path / "meta.json", {"a": 1})
    assert e.value.filename == str(tmp_path / "meta.json")
    assert list(tmp_path.iterdir()) == []
    if Path("/dev/full").exists():  # a device is never replaced by a file (nor written to)
        with pytest.raises(OSError, match="/dev/full is a character device"):
            results.write_csv(Path("/dev/full"), [{"a": 1}], ["a"])
        assert Path("/dev/full").is_char_device()


def test_replay_out_that_cannot_be_created_is_named(tmp_path, capsys):
    log = _session_log(tmp_path / "s.jsonl")
    line = cli_error(["replay", str(log), "--learners", "gradient", "--out", "/proc/rp"], capsys)
    assert "--out /proc/rp: cannot create this folder" in line


# ---------------------------------------------------------------------- 8. Ray
def test_an_unreachable_ray_address_fails_within_a_bounded_time(tmp_path):
    pytest.importorskip("ray")
    from strol_gym.benchmarks.engine.backends import check_backend

    t0 = time.perf_counter()
    args = ["run", "--env", "robot", "--learners", "gradient", "--runs", "1"]
    args += ["--backend", "ray", "--ray-address", "127.0.0.1:1", "--out", str(tmp_path / "r")]
    line = _one_error_line(_cli(args, timeout=120))
    assert "--ray-address 127.0.0.1:1: no Ray cluster reachable" in line
    assert time.perf_counter() - t0 < 90  # imports included; Ray alone retried > 120 s
    assert not (tmp_path / "r").exists()
    for address in ("bogus.invalid:1", "127.0.0.1:1"):
        with pytest.raises(ValueError, match=f"--ray-address {address}: no Ray cluster"):
            check_backend("ray", address)
    with pytest.raises(ValueError, match="--ray-address must be HOST:PORT"):
        check_backend("ray", "bogus")


# ---------------------------------------------------------------------- 9-10. interrupts
def test_ctrl_c_from_the_entry_functions_first_line_is_one_line_and_130(tmp_path):
    code = textwrap.dedent(
        """
        import os, signal, sys, time
        from strol_gym.benchmarks import cli

        real = cli.build_parser

        def interrupted_while_building(command=None):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
            return real(command)

        cli.build_parser = interrupted_while_building
        sys.exit(cli.main(["list"]))
        """
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.strip() == "interrupted"


def test_an_interrupt_surfacing_as_import_error_is_an_interrupt(monkeypatch, capsys):
    def interrupted_import(args, parser):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise ImportError("initialization failed") from None

    monkeypatch.setitem(cli.COMMANDS, "list", interrupted_import)
    assert cli.main(["list"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == cli.INTERRUPTED_NO_RESUME.format(command="list")
    assert "Traceback" not in err


def test_pool_workers_start_with_sigint_ignored():
    """A Ctrl-C while workers import reaches only the parent (no worker tracebacks)."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    with engine_pool._sigint_ignored():
        pool = ctx.Pool(1)
    with pool:
        assert pool.apply(signal.getsignal, (signal.SIGINT,)) == signal.SIG_IGN
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


WATCHED = """
import multiprocessing as mp
import os
import time

from strol_gym.benchmarks.engine import pool as runner_pool

if __name__ == "__main__":
    pool = mp.get_context("spawn").Pool(
        1, initializer=runner_pool._die_with_parent, initargs=(os.getpid(),)
    )
    print(pool.apply(os.getpid), flush=True)
    time.sleep(120)
"""


@pytest.mark.skipif(sys.platform != "linux", reason="PR_SET_PDEATHSIG is Linux's")
def test_pool_workers_die_with_a_killed_parent(tmp_path):
    (tmp_path / "watched.py").write_text(WATCHED)
    parent = subprocess.Popen(
        [sys.executable, "watched.py"], cwd=tmp_path, stdout=subprocess.PIPE, text=True
    )
    try:
        worker = int(parent.stdout.readline())
        parent.kill()
        parent.wait()
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and _alive(worker):
            time.sleep(0.1)
        assert not _alive(worker), "the worker outlived its killed parent"
    finally:
        parent.kill()


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0]
    except (FileNotFoundError, IndexError):
        return False
    return state != "Z"


# ---------------------------------------------------------------------- 11. accepted by mistake
def test_empty_out_is_refused(capsys):
    assert "--out must name a path" in cli_error(["paper", "--out", ""], capsys)
    parser = add_train_arguments(argparse.ArgumentParser())
    with pytest.raises(ValueError, match=r"--out must be a file ending in \.safetensors"):
        run_train(parser.parse_args(["--out", ""]))


def test_train_refuses_sigma_in_human_kwargs(capsys, tmp_path):
    argv = ["train", "--human-kwargs", '{"sigma": "x"}', "--out", str(tmp_path / "w.pt")]
    assert "human_kwargs must not hold ['sigma']" in cli_error(argv, capsys)


@pytest.mark.parametrize("env_id", ["StROL-Robot-v0", "StROL-Highway-v0"])
def test_env_arguments(env_id):
    with pytest.raises(ValueError, match="sigma must be a number"):
        gym.make(env_id, person={"sigma": True})
    # -1 is gymnasium's documented "no TimeLimit" (accepted, docs); built directly it is refused
    assert not isinstance(gym.make(env_id, max_episode_steps=-1), gym.wrappers.TimeLimit)
    with pytest.raises(ValueError, match="max_episode_steps must be an integer >= 1"):
        gym.spec(env_id).make(max_episode_steps=None).unwrapped.__class__(max_episode_steps=-1)
    with pytest.raises(ValueError, match="render_mode must be None or one of"):
        gym.make(env_id, render_mode=5)
    # deliberately accepted (docs): a numeric string, as a command line gives it
    env = gym.make(env_id, person={"sigma": "0.1"})
    assert env.unwrapped.person_spec.sigma == 0.1
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action must be real numbers"):
        env.step(np.array([0.1j] * env.action_space.shape[0]))
    env.close()


@pytest.mark.parametrize("env_id", ["StROL-Robot-v0", "StROL-Highway-v0"])
def test_step_before_reset_raises_in_every_env(env_id):
    env = gym.make(env_id).unwrapped
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
        env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    env.close()


def test_zero_corrections_is_a_no_teaching_control():
    """n_corrections=0 is accepted on purpose (docs): the human never corrects, θ̂ stays."""
    env = OnlineLearningWrapper(gym.make("StROL-Robot-v0", n_corrections=0), "gradient")
    env.reset(seed=0)
    theta0 = env.unwrapped.theta_hat.copy()
    for _ in range(3):
        _, _, _, _, info = env.step(np.zeros(3, dtype=np.float32))
        assert not info["is_correction"]
    np.testing.assert_array_equal(env.unwrapped.theta_hat, theta0)
    env.close()


@pytest.mark.parametrize("lam", [1e300, -1.0, True, "x"])
def test_strol_lam_is_bounded(lam):
    with pytest.raises(ValueError, match=r"lam must be a number in \[0, 1000\]"):
        make_learner("strol", task=ROBOT, lam=lam)


def test_wrapper_flags_must_be_booleans():
    env = gym.make("StROL-Robot-v0")
    with pytest.raises(ValueError, match="replace_reward must be True or False, got 'yes'"):
        OnlineLearningWrapper(env, "gradient", replace_reward="yes")
    with pytest.raises(ValueError, match="regret must be True or False"):
        OnlineLearningWrapper(env, "gradient", regret="no")
    with pytest.raises(ValueError, match="learner_kwargs must be a dict"):
        OnlineLearningWrapper(env, "gradient", learner_kwargs="lam=1")
    with pytest.raises(ValueError, match="no-such-learner"):
        OnlineLearningWrapper(env, "no-such-learner")
    env.close()
