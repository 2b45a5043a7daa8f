"""One push, one correction (StROL-Study-v2's hold-off), from outside: pushes through the
public push API (``apply_wrench``, ``hold_wrench``) on ``gym.make("StROL-Study-v2", ...)`` with
no simulated person, at study seeds never used while building the hold-off (61001-61011, and
62006-62009 for u_H with and without it, run once), the state machine on its own, and a mouse
drag sent as X events to ``strol-bench interact`` on v2 under Xvfb."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from test_interact_person import needs_x

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.envs.study.env import StudyEnvV2
from strol_gym.envs.study.people import TORQUE_LEVER
from strol_gym.envs.study.segment import PushSegmenter
from strol_gym.envs.study.versions import HOLD_OFF
from strol_gym.tasks.study import CONTROL_DT
from strol_gym.wrappers.session_log import read_session

HOLD_STEPS = round(HOLD_OFF / CONTROL_DT)
"""v2's default hold-off in 50 ms control steps (8)."""


def make(**kw) -> StudyEnvV2:
    kw.setdefault("person", None)
    return gym.make("StROL-Study-v2", **kw).unwrapped


def run(env: StudyEnvV2, n: int) -> list[dict]:
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    return [env.step(zero)[4] for _ in range(n)]


def pushes(env: StudyEnvV2, pieces: list[tuple[float, float]], axis: np.ndarray) -> list[dict]:
    """Push along ``axis`` with (newtons, seconds) pieces in a row (0 N: no push), then let
    go for 1 s; the steps' infos."""
    infos: list[dict] = []
    for newtons, seconds in pieces:
        n = round(seconds / CONTROL_DT)
        if newtons:
            env.apply_wrench(newtons * axis, duration=seconds)
        infos += run(env, n)
    return infos + run(env, 20)


def ends(infos: list[dict]) -> list[dict]:
    return [i for i in infos if i["is_correction"]]


def settled(task: int, seed: int, **kw) -> StudyEnvV2:
    """The env after 1 s along its plan and a 1 s pause (the arm near its setpoint)."""
    env = make(task=task, **kw)
    env.reset(seed=seed)
    run(env, 20)
    env.pause(1.0)
    run(env, 20)
    return env


X, Y, Z = np.eye(3)


# Pushes towards the reachable set's inside: with v2's admittance arm, +Y from y = 0.58 (Task 1)
# and two +Z pushes (Task 3) carried the cup past the arm's reach and the speed reflex stopped
# the second piece (issue 33's merge); the segmentation is what these tests are about.
@pytest.mark.parametrize(("task", "seed", "axis"), [(1, 61001, -Y), (2, 61002, -X)])
def test_a_push_that_eases_off_and_comes_back_is_one_correction(task, seed, axis):
    """30 N for 0.8 s, 10 N (below the 15 N threshold) for 0.1 s, 30 N for 0.8 s: one
    correction, ending after the hold-off, whose u_H points along the push and is larger
    than the first piece's alone (the arm stayed where the first piece left it)."""
    env = settled(task, seed)
    infos = pushes(env, [(30.0, 0.8), (10.0, 0.1), (30.0, 0.8)], axis)
    (end,) = ends(infos)
    assert infos[-1]["corrections"] == 1
    rec = end["correction_record"]
    assert rec["end_time"] - rec["start_time"] == pytest.approx(1.7 + HOLD_OFF, abs=1e-6)
    assert end["correction_time"] == pytest.approx(1.6, abs=1e-6)  # the seconds above 15 N
    u = end["u_h"][:3]
    assert u @ axis / np.linalg.norm(u) > math.cos(math.radians(25.0))

    single = settled(task, seed)
    (one,) = ends(pushes(single, [(30.0, 0.8)], axis))
    assert np.linalg.norm(u) > 1.5 * np.linalg.norm(one["u_h"][:3])


def test_the_published_rule_cuts_the_same_push_in_two():
    """hold_off=0 ends a correction at the first step below the threshold (v0/v1's rule)."""
    env = settled(1, 61003, hold_off=0.0)
    infos = pushes(env, [(30.0, 0.8), (10.0, 0.1), (30.0, 0.8)], X)
    assert len(ends(infos)) == 2


@pytest.mark.parametrize(("task", "seed", "axis"), [(1, 61004, -Y), (3, 61005, -Z)])
def test_two_pushes_a_second_apart_are_two_corrections(task, seed, axis):
    env = settled(task, seed)
    infos = pushes(env, [(30.0, 0.8), (0.0, 1.0), (30.0, 0.8)], axis)
    first, second = ends(infos)
    assert infos[-1]["corrections"] == 2
    for end in (first, second):
        u = end["u_h"][:3]
        assert np.linalg.norm(u) > 0.04
        assert u @ axis / np.linalg.norm(u) > math.cos(math.radians(25.0))


CASES = [
    (1, 62006, X, 0),
    (1, 62007, -Z, 30),
    (2, 62008, Y, 0),
    (2, 62008, -X, 30),
    (3, 62009, -Y, 0),
    (3, 62009, X + Z, 30),
]
"""(task, seed, direction, steps along the plan before the push: 0 = settled, else moving)."""


@pytest.mark.parametrize(("task", "seed", "axis", "moving"), CASES)
def test_the_hold_off_does_not_shrink_u_h(task, seed, axis, moving):
    """A 30 N push for 0.8 s: u_H with a 0.3 s hold-off (and v2's default) within 10 % of u_H
    without one (the arm yields through the hold-off, and u_H is still the pushed pose minus
    the counterfactual over the whole correction)."""
    u = []
    for hold_off in (0.0, 0.3, HOLD_OFF):
        if moving:
            env = make(task=task, hold_off=hold_off)
            env.reset(seed=seed)
            run(env, moving)
        else:
            env = settled(task, seed, hold_off=hold_off)
        infos = pushes(env, [(30.0, 0.8)], axis / np.linalg.norm(axis))
        (end,) = ends(infos)
        rec = end["correction_record"]
        assert rec["end_time"] - rec["start_time"] == pytest.approx(0.8 + hold_off, abs=1e-6)
        u.append(end["u_h"][:3])
    for other in u[1:]:
        assert np.linalg.norm(other - u[0]) <= 0.10 * np.linalg.norm(u[0]), u


def test_a_jittery_drag_held_each_step_is_one_correction():
    """What interact hands the env: a wrench held each step, here a drag that grows from 0 to
    40 N over 1.35 s with one-step dips below the threshold every few steps (a mouse's
    perturbation), then let go. v2: one correction; v1 (no hold-off): one per stretch. (45 N
    along −y would load joint 5 past 0.9 of its motor's torque here: v2's torque reflex.)"""
    rng = np.random.default_rng(36)
    force = np.minimum(np.arange(1, 41) * 1.5, 40.0)
    force[rng.choice(np.arange(12, 40), size=7, replace=False)] = 8.0
    counts = {}
    for env_id in ("StROL-Study-v2", "StROL-Study-v1"):
        env = gym.make(env_id, person=None, task=1).unwrapped
        env.reset(seed=61010)
        run(env, 20)
        infos = []
        for f in force:
            env.hold_wrench((0.0, -f, 0.0))
            infos += run(env, 1)
        env.hold_wrench((0.0, 0.0, 0.0))
        infos += run(env, 20)
        assert not any(i["reflex"] for i in infos)
        counts[env_id] = len(ends(infos))
    assert counts["StROL-Study-v2"] == 1
    assert counts["StROL-Study-v1"] >= 5


def test_info_says_when_a_correction_is_under_way_and_when_it_ended():
    env = settled(1, 61011)
    infos = pushes(env, [(30.0, 0.5)], X)
    phases = [i["correction_phase"] for i in infos]
    idle = 30 - 10 - HOLD_STEPS - 1
    assert phases == ["pushing"] * 10 + ["holding"] * HOLD_STEPS + ["ended"] + ["idle"] * idle
    assert [i["correction_active"] for i in infos] == [p in ("pushing", "holding") for p in phases]
    assert phases.index("ended") == [i["is_correction"] for i in infos].index(True)


@pytest.mark.parametrize("value", [-0.1, 0.51, float("nan"), float("inf"), "soon", True])
def test_the_hold_off_argument_is_checked(value):
    with pytest.raises((TypeError, ValueError), match=r"hold_off must be a number in \[0, 0.5\]"):
        make(hold_off=value)


def test_only_versions_with_a_hold_off_take_the_argument():
    assert make(hold_off=0.5).hold_off == 0.5
    assert make().hold_off == HOLD_OFF
    with pytest.raises(ValueError, match="hold_off"):
        gym.make("StROL-Study-v1", person=None, hold_off=0.3)


def test_the_segmenter_on_its_own():
    """The state machine alone: the hold-off in steps, a comeback within it, a brake."""
    seg = PushSegmenter.for_hold_off(15.0, 0.3, 0.05)
    assert seg.hold_steps == 6
    felt = [20.0, 20.0, 5.0, 5.0, 20.0] + [0.0] * 6 + [0.0, 20.0]
    events = [seg.feed(f) for f in felt]
    assert events == ["start", None, "release", None, None, "release", *[None] * 5, "end", "start"]
    assert seg.active
    assert seg.feed(50.0, can_push=False) == "release"  # braked: no push
    seg.cancel()
    assert not seg.active and seg.feed(5.0) is None
    first_drop = PushSegmenter.for_hold_off(15.0, 0.0, 0.05)
    assert [first_drop.feed(f) for f in (20.0, 10.0, 20.0)] == ["start", "end", "start"]


# A drag on link 7 selected in code: this test is about how a drag is cut into corrections;
# selecting by a person's click is test_interact_person's.
ARM_DRIVER = """
import subprocess
import sys
from pathlib import Path

import mujoco
from strol_gym.benchmarks.cli import main
from strol_gym.benchmarks.sessions import interact

ready = Path(sys.argv[1])


class Selected(interact._Passive):
    # The real viewer with link 7 selected, as a person's double-click on it leaves it.

    def __init__(self, model, data):
        super().__init__(model, data)
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "panda0_link7")
        with self.handle.lock():
            self.handle.perturb.select = body
        # The viewer maps its window on a thread of its own; X events sent before that are
        # lost (under load a drag once read 0 N), so the physics starts once it is visible.
        find = ["xdotool", "search", "--sync", "--onlyvisible", "--name", "^MuJoCo"]
        subprocess.run(find, check=True, timeout=120, stdout=subprocess.DEVNULL)
        ready.write_text("selected")


interact.passive_viewer = Selected
sys.exit(main(sys.argv[2:]))
"""

DRAG = """
ready="$1"; shift
"$@" &
pid=$!
for i in $(seq 1 1200); do [ -f "$ready" ] && break; sleep 0.1; done
sleep 1.5
# Ctrl + right-drag from the window's centre: the viewer's force on the selected body
xdotool mousemove 512 384 keydown ctrl mousedown 3
for i in $(seq 1 20); do xdotool mousemove_relative -- 4 -3; sleep 0.05; done
# held 3 s: the viewer reads the mouse only when it draws a frame, and with software rendering
# on a loaded machine a frame can take a second (held 1 s, the drag once never reached the arm)
sleep 3.0
xdotool mouseup 3 keyup ctrl
wait $pid
"""


def drag_session(tmp_path: Path, drag: str, max_steps: int) -> tuple[Path, list[dict]]:
    """`strol-bench interact --task 1` with link 7 selected, under Xvfb, while the shell script
    ``drag`` sends its X events: the session log's path and its records."""
    log, ready = tmp_path / "arm.jsonl", tmp_path / "ready"
    (tmp_path / "driver.py").write_text(ARM_DRIVER)
    (tmp_path / "drag.sh").write_text(drag)
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    run = [sys.executable, str(tmp_path / "driver.py"), str(ready), "interact", "--task", "1"]
    run += ["--max-steps", str(max_steps), "--log", str(log)]
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", "bash", str(tmp_path / "drag.sh")]
    done = subprocess.run(
        [*cmd, str(ready), *run], capture_output=True, text=True, timeout=240, env=env
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return log, [json.loads(t) for t in log.read_text().splitlines()]


SLOW_DRAG = DRAG.replace(
    "$(seq 1 20); do xdotool mousemove_relative -- 4 -3",
    "$(seq 1 16); do xdotool mousemove_relative -- 2 -2",
)
"""test_interact_person's Ctrl + right-drag, slower (45 px in 0.8 s, not 100 px in 1 s)."""


@needs_x
def test_a_mouse_drag_on_v2_is_cut_only_where_its_force_rested_under_xvfb(tmp_path):
    """Ctrl + right-drag on the selected link, sent as X events, interact's session on v2: the
    drag reaches the arm (a correction, or a reflex where the viewer's force outgrew it), and
    every correction in the log ended only after its force had stayed at or below 15 N for the
    whole hold-off (the trace's last ``hold_off / dt`` samples), with no rest that long inside
    it. At idle this drag is one correction; on a loaded machine the mouse's events arrive in
    bursts, the yielding arm catches up with the pointer between them and the force rests, so
    the drag may be cut there, as a person's pause would cut it. On v1 one such drag became 13
    corrections: every sag below 15 N ended one."""
    assert SLOW_DRAG != DRAG
    # 240 steps (12 s): room for a drag whose X events a loaded machine delivers late (at 130
    # steps a drag once left no trace in the log on a loaded machine; the cause not confirmed)
    log, lines = drag_session(tmp_path, SLOW_DRAG, max_steps=240)
    assert lines[0]["env_id"] == "StROL-Study-v2"  # interact builds strol-bench study's v2
    corrections = [r for r in lines if r["type"] == "correction"]
    reflexes = [r for r in lines if r["type"] == "event" and r["kind"] == "reflex"]
    assert corrections or reflexes, ("the drag never reached the arm", lines[-3:])
    rest = PushSegmenter.for_hold_off(15.0, HOLD_OFF, CONTROL_DT).hold_steps
    for c in corrections:
        trace = c["trace"]
        felt = np.linalg.norm(np.array(trace["force"]), axis=1)
        felt += np.linalg.norm(np.array(trace["torque"]), axis=1) / TORQUE_LEVER
        above = felt > 15.0
        assert above.any() and np.linalg.norm(c["u_h"]) > 0.0
        assert not above[-rest:].any() and above[-rest - 1], (felt.round(1), rest)
        runs, n = [], 0
        for a in above[: -rest - 1]:
            n = 0 if a else n + 1
            runs.append(n)
        assert max(runs, default=0) < rest, (felt.round(1), rest)
    read_session(log)
