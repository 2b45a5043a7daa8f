"""strol-bench interact and replay: a viewer's push becomes a logged, replayable correction.

The fake viewer writes its wrench the way MuJoCo's passive viewer does: ``sync()`` zeroes
``xfrc_applied`` and then writes the mouse's perturbation on the selected body.
"""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from strol_gym.benchmarks.cli import main
from strol_gym.benchmarks.sessions.interact import (
    DRAG_STIFFNESS,
    Drag,
    panel_text,
    run_interactive,
)
from strol_gym.envs.study.segment import PushSegmenter
from strol_gym.envs.study.versions import HOLD_OFF
from strol_gym.tasks.study import CONTROL_DT
from strol_gym.wrappers.session_log import SessionLogError, read_session

PUSH_START, PUSH_STEPS = 10, 20  # control steps (0.05 s): a 1 s push from t = 0.5 s
HOLD_STEPS = PushSegmenter.for_hold_off(15.0, HOLD_OFF, CONTROL_DT).hold_steps
"""v2 ends a correction after its force has rested at or below 15 N this many steps."""


class FakeViewer:
    """Drags the cup with ``force`` N during syncs [start, start + steps): the drag's point is
    put ``force / DRAG_STIFFNESS`` m from the cup, as a mouse leaves it; ``held``: keys."""

    def __init__(
        self,
        model,
        data,
        force=(0.0, 30.0, 0.0),
        start=PUSH_START,
        steps=PUSH_STEPS,
        held=(),
        azimuth=150.0,
        held_steps=None,
    ):
        self.model, self.data = model, data
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "cup")
        self.force = np.asarray(force, dtype=float)
        self.window = range(start, start + steps)
        self.held = frozenset(held)
        self.held_steps = held_steps  # syncs during which ``held`` is held (None: always)
        self.camera = azimuth
        self.syncs = 0
        self.texts = None
        self.history = []
        self.plans = []
        self.targets = []
        self.show_target = False  # the F8 key
        self.show_panel = True  # the F9 key
        self.closed = False
        self.lost = ""
        self.want_cup = False
        self.selected = (0, np.zeros(3))
        self.active, self.ref = 0, np.zeros(3)

    def sync(self) -> None:
        self.data.xfrc_applied[:] = 0.0
        self.active = 0
        if self.syncs in self.window:
            self.active = int(mujoco.mjtPertBit.mjPERT_TRANSLATE)
            self.ref = self.data.site_xpos[self.site] + self.force / DRAG_STIFFNESS
        self.syncs += 1

    def drag(self) -> Drag:
        body, local = self.selected
        return Drag(body, self.active, self.ref.copy(), np.array([1.0, 0, 0, 0]), local)

    def select(self, body, localpos) -> None:
        self.selected = (body, np.array(localpos))

    def held_keys(self):
        if self.held_steps is None or self.syncs in self.held_steps:
            return self.held
        return frozenset()

    def azimuth(self) -> float:
        return self.camera

    def is_running(self) -> bool:
        return not self.closed

    def set_texts(self, texts) -> None:
        self.texts = texts
        self.history.append(texts)

    def draw_plan(self, points, target=None) -> None:
        self.plans.append(np.array(points))
        self.targets.append(None if target is None else np.array(target))

    def close(self) -> None:
        self.closed = True


def cli(argv: list[str]) -> int:
    """strol-bench's exit status (argparse-style errors raise SystemExit)."""
    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code)


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """One headless interactive session on Task 1 with StROL: a 30 N push along +y for 1 s."""
    path = tmp_path_factory.mktemp("interact") / "s.jsonl"
    viewers = []

    def factory(model, data):
        viewers.append(FakeViewer(model, data))
        return viewers[-1]

    log, info = run_interactive(
        task=1,
        learner="strol",
        seed=20010,
        log=path,
        max_steps=50,
        realtime=False,
        viewer_factory=factory,
    )
    return log, info, viewers[0]


def test_push_is_one_logged_correction_and_the_learner_updates(session):
    log, info, viewer = session
    assert viewer.closed and viewer.syncs == 50
    assert info["corrections"] == 1
    assert info["correction_time"] == pytest.approx(1.0, abs=0.051)
    s = read_session(log)
    assert s.header["learner"] == "strol" and s.header["task"] == "study-task1-v2"
    assert s.header["env_kwargs"]["person"] is None
    (ep,) = s.episodes
    (c,) = ep.corrections
    assert c["u_h"][1] > 0.02  # the hand moved along +y by > 2 cm
    lines = [json.loads(t) for t in log.read_text().splitlines()]
    rec = next(r for r in lines if r["type"] == "correction")
    force = np.array(rec["trace"]["force"])
    # v2: the trace runs through the hold-off (the force at rest) that ended the correction
    assert len(rec["trace"]["t"]) == PUSH_STEPS + HOLD_STEPS
    np.testing.assert_allclose(force[:PUSH_STEPS], np.tile([0.0, 30.0, 0.0], (PUSH_STEPS, 1)))
    np.testing.assert_allclose(force[PUSH_STEPS:], 0.0)
    assert not np.allclose(rec["theta_hat_before"], rec["theta_hat_after"])
    np.testing.assert_allclose(rec["theta_hat_before"], ep.theta_hat0)
    np.testing.assert_allclose(info["theta_hat"], rec["theta_hat_after"])
    assert lines[-1]["type"] == "end" and lines[-1]["reason"] == "max_steps"
    # the overlay shows the correction time; blind (the default), no θ̂ or φ
    shown = "\n".join(t[2] + t[3] for t in viewer.texts)
    assert "correction time 1.00 s" in panel_text(viewer.texts)
    assert "theta_hat" not in shown and "pitcher:" not in shown
    assert lines[-1]["interrupted"] is False


def test_panel_tells_how_to_push_what_to_teach_and_cues_the_correction(session):
    from strol_gym.benchmarks.sessions.interact import teach_words
    from strol_gym.tasks.study import StudyTask1

    log, _, viewer = session
    how = panel_text(viewer.texts)
    task = StudyTask1()
    assert "Ctrl + right-drag" in how and ">15 N a correction" in how and ">100 N" in how
    assert "W/S A/D E/Q push away/back" in how and "END close the window" in how
    assert how.endswith("TEACH " + teach_words(task.feature_names, task.theta_star))
    assert all(len(t[2]) <= 500 and len(t[3]) <= 500 for t in viewer.texts)  # mjMAXOVERLAY
    # the panel stays in the top corners: the table, pitcher and plate below stay in view
    grids = {t[1] for texts in viewer.history for t in texts}
    assert grids <= {mujoco.mjtGridPos.mjGRID_TOPLEFT, mujoco.mjtGridPos.mjGRID_TOPRIGHT}
    assert teach_words(("pitcher", "table"), np.array([-1.0, 0.5])) == (
        "carry the cup away from the pitcher, low, near the table"
    )
    cues = ["\n".join(t[2] for t in texts[1:]) for texts in viewer.history]
    pushing = [k for k, c in enumerate(cues) if "PUSH COUNTS: 30 N > 15 N" in c]
    assert pushing == list(range(PUSH_START, PUSH_START + PUSH_STEPS))
    (c,) = read_session(log).episodes[0].corrections
    u_h = "CORRECTION RECORDED: u_H = (" + ", ".join(f"{v:+.3f}" for v in c["u_h"]) + ")"
    recorded = [k for k, c in enumerate(cues) if u_h in c]
    assert recorded and recorded[0] == PUSH_START + PUSH_STEPS + HOLD_STEPS  # after the hold-off
    # the plan: drawn at reset, redrawn after the correction (θ̂ changed)
    assert len(viewer.plans) >= 2 and viewer.plans[0].shape[1] == 3
    assert not np.array_equal(viewer.plans[0], viewer.plans[-1])


def test_replay_two_learners(session, tmp_path, capsys):
    log, info, _ = session
    out = tmp_path / "replay"
    assert cli(["replay", str(log), "--learners", "strol,gradient", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "StROL" in printed and "Gradient" in printed
    with (out / "replay.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 2  # two learners x (θ̂0, after the one correction)
    strol = [r for r in rows if r["learner"] == "strol"]
    # replaying the logged learner reproduces the session's θ̂
    final = np.array([float(strol[-1][f"theta_{i}"]) for i in range(3)])
    np.testing.assert_allclose(final, info["theta_hat"], atol=1e-5)
    grad = [r for r in rows if r["learner"] == "gradient"]
    assert grad[-1]["theta_0"] != strol[-1]["theta_0"]
    assert (out / "replay_theta.png").stat().st_size > 1000


def test_bad_log_names_file_and_line(session, tmp_path, capsys):
    log, _, _ = session
    lines = log.read_text().splitlines()
    bad = tmp_path / "bad.jsonl"
    rec = next(json.loads(t) for t in lines if '"type": "correction"' in t)
    rec["u_h"] = [1.0, "x", 0.0]
    bad.write_text("\n".join([lines[0], lines[1], json.dumps(rec)]) + "\n")
    with pytest.raises(SessionLogError, match=rf"{bad}:3: 'u_h'"):
        read_session(bad)
    assert cli(["replay", str(bad), "--learners", "strol"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:3" in err and "Traceback" not in err
    notjson = tmp_path / "notjson.jsonl"
    notjson.write_text(lines[0] + "\n{oops\n")
    assert cli(["replay", str(notjson), "--learners", "strol"]) == 2
    assert f"{notjson}:2: not JSON" in capsys.readouterr().err
    assert cli(["replay", str(tmp_path / "missing.jsonl"), "--learners", "strol"]) == 2


def test_cli_bad_inputs_exit_2(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert cli(["interact", "--task", "4"]) == 2
    assert "--task must be 1, 2 or 3" in capsys.readouterr().err
    assert cli(["interact", "--task", "1"]) == 2
    err = capsys.readouterr().err
    assert "xvfb-run -a strol-bench interact" in err and "StROL-Study-v2" in err
    with pytest.raises(ValueError, match="task must be 1, 2 or 3"):
        run_interactive(task=5, viewer_factory=FakeViewer)


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run is not installed")
def test_real_passive_viewer_under_xvfb(tmp_path):
    """The real viewer opens on a virtual display, steps, and the session is logged."""
    log = tmp_path / "xvfb.jsonl"
    cmd = [
        "xvfb-run",
        "-a",
        "-s",
        "-screen 0 1024x768x24",
        sys.executable,
        "-m",
        "strol_gym.benchmarks.cli",
        "interact",
        "--task",
        "1",
        "--max-steps",
        "20",
        "--fast",
        "--log",
        str(log),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    s = read_session(log)
    assert s.header["extra"]["interact"]["max_steps"] == 20
    end = json.loads(log.read_text().splitlines()[-1])
    assert end["type"] == "end" and end["steps"] == 20 and end["corrections"] == 0


def test_t_key_shows_the_plan_for_theta_star(tmp_path):
    """With the T key's flag set, the plan for θ* (from the cup's pose) is drawn beside the
    robot's own plan."""
    from strol_gym.tasks.study import StudyTask1V2

    viewers = []

    def factory(model, data):
        viewers.append(FakeViewer(model, data, steps=0))
        viewers[-1].show_target = True
        return viewers[-1]

    log, _ = run_interactive(
        task=1,
        seed=3,
        log=tmp_path / "t.jsonl",
        max_steps=3,
        realtime=False,
        viewer_factory=factory,
    )
    (viewer,) = viewers
    assert viewer.targets[0] is not None and viewer.targets[0].shape[1] == 3
    task = StudyTask1V2()  # v2's Task: its planner walks the reachable set
    x0 = np.array(json.loads(log.read_text().splitlines()[1])["x0"])
    start = viewer.targets[0][0]  # the cup where the key was read (Task 1's state is x, y, z)
    assert np.linalg.norm(start - x0) < 0.01
    planned = task.plan(task.theta_star[None], start[None])[0]
    np.testing.assert_allclose(viewer.targets[0], planned, atol=1e-9)
    assert not np.allclose(viewer.plans[0][-1], viewer.targets[0][-1])  # θ̂0 ≠ θ*


@pytest.mark.parametrize("task", [1, 2])
def test_a_person_meets_the_task_and_g_hat_of_strol_bench_study(task):
    """interact's env, Task and StROL's ĝ are those `strol-bench study` builds (its worker's
    own construction), not v0's."""
    import gymnasium as gym
    import torch

    from strol_gym.benchmarks.experiments.study import study_config
    from strol_gym.benchmarks.sessions.interact import session_env
    from strol_gym.learners.registry import make_learner

    # the study's default version (v2), its Task and ĝ
    (exp,) = study_config(tasks=(task,), users=1).experiments
    env = gym.make(exp.env_id, **exp.env_kwargs())
    study_learner = make_learner("strol", task=env.unwrapped.task)
    person = session_env(task, "strol")
    assert person.unwrapped.spec.id == exp.env_id
    assert type(person.unwrapped.task) is type(env.unwrapped.task)
    assert person.unwrapped.task.version == env.unwrapped.task.version >= 1
    assert person.unwrapped.person is None  # no simulated person pushes
    ours, theirs = person.learner.model.state_dict(), study_learner.model.state_dict()
    assert ours.keys() == theirs.keys()
    for k in ours:
        assert torch.equal(ours[k], theirs[k]), k
    assert person.learner.checkpoint == study_learner.checkpoint
    env.close()
    person.close()


def _run(tmp_path, name, **kwargs):
    viewers = []

    def factory(model, data):
        viewers.append(FakeViewer(model, data, **kwargs))
        return viewers[-1]

    return viewers, factory, tmp_path / f"{name}.jsonl"


def test_a_shove_above_the_reflex_shows_on_the_panel_and_is_logged(tmp_path):
    """A long drag with Shift (harder) held: the drag's 250 N is capped at 1.25 x the reflex,
    125 N, above the reflex: the arm brakes."""
    viewers, factory, path = _run(
        tmp_path, "shove", force=(0.0, 250.0, 0.0), steps=6, held={"shift"}
    )
    _, info = run_interactive(
        task=1, log=path, max_steps=30, realtime=False, viewer_factory=factory
    )
    (viewer,) = viewers
    assert info["corrections"] == 0 and info["reflexes"] == 1
    lines = [json.loads(t) for t in path.read_text().splitlines()]
    (event,) = [r for r in lines if r["type"] == "event" and r["kind"] == "reflex"]
    assert event["kind"] == "reflex" and event["reflex_force"] == 100.0
    np.testing.assert_allclose(event["force"], [0.0, 125.0, 0.0])
    assert event["step"] == PUSH_START
    assert not any(r["type"] == "correction" for r in lines)
    read_session(path)  # the reader takes event lines
    cues = ["\n".join(t[2] for t in texts[1:]) for texts in viewer.history]
    too_hard = [k for k, c in enumerate(cues) if "TOO HARD: the arm braked, no correction" in c]
    assert too_hard[0] == PUSH_START and "(125 N > 100 N)" in cues[PUSH_START]
    assert not any("PUSH COUNTS" in c for c in cues)


def test_a_push_a_joint_cannot_bear_brakes_below_the_force_reflex_and_the_panel_says_why(
    tmp_path,
):
    """v2 (interact's env) also brakes on a push that would overload a joint: a 60 N push along
    x at Task 1's start does, below the 100 N reflex, and the panel must not claim 60 N > 100 N."""
    from strol_gym.benchmarks.sessions.interact import JOINT_LIMIT

    viewers, factory, path = _run(tmp_path, "joint", force=(60.0, 0.0, 0.0), steps=6)
    _, info = run_interactive(
        task=1, log=path, max_steps=30, realtime=False, viewer_factory=factory
    )
    (viewer,) = viewers
    assert info["corrections"] == 0 and info["reflexes"] == 1
    assert JOINT_LIMIT in panel_text(viewer.texts)
    cue = "\n".join(t[2] for t in viewer.history[PUSH_START][1:])
    assert "TOO HARD" in cue and "(60 N: a joint's limit)" in cue and "> 100 N" not in cue


def test_blind_by_default_and_the_panel_toggles(tmp_path):
    """--blind (default) hides θ̂ and φ, --no-blind shows them; the log keeps θ̂ either way;
    with the panel key's flag off only a one-line hint stays."""
    from strol_gym.benchmarks.sessions.interact import PANEL_HIDDEN

    for blind in (True, False):
        viewers, factory, path = _run(tmp_path, f"b{blind}", steps=0)
        run_interactive(
            task=1, log=path, max_steps=3, realtime=False, viewer_factory=factory, blind=blind
        )
        shown = "\n".join(t[2] for t in viewers[0].texts)
        assert ("theta_hat" in shown and " / phi " in shown) is (not blind)
        assert read_session(path).episodes[0].theta_hat0 is not None
        assert json.loads(path.read_text().splitlines()[0])["extra"]["interact"]["blind"] is blind
    viewers, factory, path = _run(tmp_path, "hidden", steps=0)

    def hidden(model, data):
        viewer = factory(model, data)
        viewer.show_panel = False
        return viewer

    run_interactive(task=1, log=path, max_steps=3, realtime=False, viewer_factory=hidden)
    assert viewers[0].texts[0][2] == PANEL_HIDDEN


def test_our_keys_are_free_in_the_viewer():
    """F8 and F9 are none of MuJoCo's viewer's keys (every letter is a visual flag)."""
    from strol_gym.benchmarks.sessions.interact import PANEL_KEY, TARGET_KEY

    letters = {row[2] for row in (*mujoco.mjVISSTRING, *mujoco.mjRNDSTRING) if row[2]}
    assert set("ABCDEFGHIJKLMNOPQRSTUVWXYZ") <= letters  # no letter is free
    glfw_f1 = 290
    assert {TARGET_KEY - glfw_f1 + 1, PANEL_KEY - glfw_f1 + 1} == {8, 9}  # F8, F9 (F1-F7 used)


def _angle(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    cos = np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b)
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


@pytest.mark.parametrize("azimuth", [150.0, 60.0])
def test_a_key_push_is_one_correction_where_the_camera_looks(tmp_path, azimuth):
    """W held 1.5 s: the push grows like a hand's to 40 N away from the camera (laid flat on the
    table), the panel shows its size, and it becomes one correction whose u_H points within
    30 degrees of W's direction, whichever way the camera looks."""
    from strol_gym.benchmarks.sessions.keys import camera_axes

    viewers, factory, path = _run(
        tmp_path, "w", steps=0, held={"w"}, held_steps=range(5, 35), azimuth=azimuth
    )
    _, info = run_interactive(
        task=1, log=path, max_steps=60, realtime=False, viewer_factory=factory
    )
    (c,) = read_session(path).episodes[0].corrections
    away = camera_axes(azimuth)[:, 1]
    assert _angle(c["u_h"], away) < 30.0, (c["u_h"], away)
    lines = [json.loads(t) for t in path.read_text().splitlines()]
    force = np.array(next(r for r in lines if r["type"] == "correction")["trace"]["force"])
    sizes = np.linalg.norm(force, axis=1)
    assert sizes.max() == pytest.approx(40.0) and sizes[0] < 40.0  # it grew to 40 N
    assert all(_angle(f, away) < 1e-6 for f in force[sizes > 0])
    panels = [panel_text(texts) for texts in viewers[0].history]
    assert any("key push 40 N, 0.0 N m" in p for p in panels)
    assert info["corrections"] == 1 and info["reflexes"] == 0


def test_duration_is_the_step_limit_and_the_end_line_says_time_up(tmp_path):
    """--duration 100 lasts 100 simulated seconds (the registered limit, 60 s, no longer ends it
    first); the end line says "time up" with the simulated time."""
    viewers, factory, path = _run(tmp_path, "d", steps=0)
    _, info = run_interactive(
        task=1, log=path, duration=100.0, realtime=False, viewer_factory=factory
    )
    end = json.loads(path.read_text().splitlines()[-1])
    assert end["type"] == "end" and end["reason"] == "time up" and info["end_reason"] == "time up"
    assert end["steps"] == 2000 and end["sim_time"] == pytest.approx(100.0)
    assert "time 100.0 s of 100 s" in panel_text(viewers[0].texts)


def test_sigterm_ends_the_session_with_its_reason_and_130(tmp_path, monkeypatch, capsys):
    """SIGTERM (a terminal closed, a job stopped) writes the end line, as Ctrl-C does."""
    import os
    import signal

    from strol_gym.benchmarks.sessions import interact

    class Terminated(FakeViewer):
        def sync(self):
            super().sync()
            if self.syncs == 5:
                os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(interact, "passive_viewer", Terminated)
    log = tmp_path / "t.jsonl"
    before = signal.getsignal(signal.SIGTERM)  # another test in this worker may have set one
    assert cli(["interact", "--task", "1", "--fast", "--log", str(log)]) == 130
    end = json.loads(log.read_text().splitlines()[-1])
    assert end["reason"] == "terminated" and end["interrupted"] is True
    assert end["steps"] >= 4 and end["sim_time"] == pytest.approx(end["steps"] * CONTROL_DT)
    out = capsys.readouterr()
    assert "session ended: terminated" in out.out and "interrupted:" in out.err
    assert signal.getsignal(signal.SIGTERM) is before  # put back


def test_each_mode_has_its_own_help(capsys):
    for argv, words in (
        (["interact", "--help"], "Push the study arm"),
        (["interact", "arm", "--help"], "Push the study arm"),
        (["interact", "car", "--help"], "Drive the blue (human) car"),
        (["interact", "--env", "highway", "--help"], "Drive the blue (human) car"),
    ):
        assert cli(argv) == 0
        text = " ".join(capsys.readouterr().out.split())
        assert words in text and "END:" in text and "LOG:" in text, argv
    assert cli(["interact", "car", "--env", "robot", "--task", "9"]) == 2


def test_a_gamepad_push_is_one_correction(tmp_path):
    """The left stick pushed forward (the standard mapping's axis 1 at -1) for 1.5 s: one
    correction away from the camera, as W gives."""
    from strol_gym.benchmarks.sessions.keys import Pad, camera_axes

    steps = iter(range(10_000))

    def pad():
        k = next(steps)
        return Pad.of([0.0, -1.0 if 5 <= k < 35 else 0.0, 0.0, 0.0], [0.0] * 17)

    _, factory, path = _run(tmp_path, "pad", steps=0)
    _, info = run_interactive(
        task=1, log=path, max_steps=60, realtime=False, viewer_factory=factory, pad=pad
    )
    (c,) = read_session(path).episodes[0].corrections
    assert _angle(c["u_h"], camera_axes(150.0)[:, 1]) < 30.0, c["u_h"]
    assert info["corrections"] == 1


def test_a_drag_pushes_by_its_length_in_metres_from_mujocos_own_perturbation():
    """MuJoCo's mjv_initPerturb on the cup gives no push; then 5 cm of drag = 20 N along it,
    0.1 rad of turn = 3 N m about it (Task 2), a 50 cm drag stops at the cap."""
    from strol_gym.benchmarks.sessions.interact import drag_wrench, session_env

    env = session_env(2)
    env.reset(seed=1)
    m, d = env.unwrapped.model, env.unwrapped.data
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "cup")
    body = int(m.site_bodyid[site])
    cam, opt, pert = mujoco.MjvCamera(), mujoco.MjvOption(), mujoco.MjvPerturb()
    scn = mujoco.MjvScene(m, 1000)
    mujoco.mjv_defaultFreeCamera(m, cam)
    mujoco.mjv_updateScene(m, d, opt, pert, cam, mujoco.mjtCatBit.mjCAT_ALL, scn)
    pert.select, pert.localpos[:] = body, m.site_pos[site]
    mujoco.mjv_initPerturb(m, d, scn, pert)
    both = int(mujoco.mjtPertBit.mjPERT_TRANSLATE) | int(mujoco.mjtPertBit.mjPERT_ROTATE)

    def push(refselpos, refquat):
        drag = Drag(body, both, np.array(refselpos), np.array(refquat), pert.localpos.copy())
        return drag_wrench(m, d, drag, site, True, (80.0, 8.0))

    force, torque = push(pert.refselpos, pert.refquat)
    np.testing.assert_allclose(np.r_[force, torque], 0.0, atol=1e-9)
    force, _ = push(pert.refselpos + np.array([0.05, 0.0, 0.0]), pert.refquat)
    np.testing.assert_allclose(force, [20.0, 0.0, 0.0], atol=1e-9)
    turned = np.zeros(4)
    mujoco.mju_mulQuat(turned, [np.cos(0.05), 0.0, 0.0, np.sin(0.05)], pert.refquat)
    _, torque = push(pert.refselpos, turned)
    np.testing.assert_allclose(torque, [0.0, 0.0, 3.0], atol=1e-6)
    force, _ = push(pert.refselpos + np.array([0.0, 0.5, 0.0]), pert.refquat)
    np.testing.assert_allclose(force, [0.0, 80.0, 0.0], atol=1e-9)
    env.close()
