"""A person at the car, as X events: strol-bench interact --env highway under Xvfb, arrow keys
pressed with xdotool in highway-env's window, the session log read back and replayed."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from strol_gym.benchmarks.cli import main
from strol_gym.benchmarks.sessions.drive import run_drive
from strol_gym.wrappers.session_log import read_session

needs_x = pytest.mark.skipif(
    shutil.which("xvfb-run") is None or shutil.which("xdotool") is None,
    reason="xvfb-run or xdotool is not installed (apt-get install xvfb xdotool)",
)

PERSON = """
log="$1"; shift
"$@" &
pid=$!
# the window opens at reset, when the log's episode line is written; with no window manager
# the keys go to the window under the pointer (the screen's centre, where the window sits)
for i in $(seq 1 1200); do
  grep -q '"type": "episode"' "$log" 2>/dev/null && break
  sleep 0.1
done
xdotool mousemove 512 384
sleep 1.2
xdotool keydown Up; sleep 1.2; xdotool keyup Up
sleep 1.2
xdotool keydown Left; sleep 1.2; xdotool keyup Left
wait $pid
"""


@needs_x
def test_a_person_drives_the_car_with_keys_under_xvfb(tmp_path):
    log = tmp_path / "drive.jsonl"
    script = tmp_path / "person.sh"
    script.write_text(PERSON)
    env = {k: v for k, v in os.environ.items() if k != "SDL_VIDEODRIVER"}
    cli = [sys.executable, "-m", "strol_gym.benchmarks.cli", "interact", "--env", "highway"]
    cli += ["--duration", "8", "--log", str(log)]
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", "bash", str(script), str(log), *cli]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=180, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "real-time factor" in done.stdout
    session = read_session(log)
    (ep,) = session.episodes
    a_max = np.array([5.0, 0.02])
    u = np.array([c["u_h"] for c in ep.corrections])
    # the Up key: positive accelerations, no steering; then Left: negative steering only
    up, left = u[u[:, 0] > 0], u[u[:, 1] < 0]
    assert len(up) >= 2 and len(left) >= 2, u
    assert np.all(np.abs(u) <= a_max + 1e-9)
    assert np.any(np.isclose(up[:, 0], a_max[0])) and np.allclose(up[:, 1], 0.0)
    assert np.allclose(left[:, 0], 0.0) and np.any(np.isclose(left[:, 1], -a_max[1]))
    assert len(u) == len(up) + len(left)  # no key, no correction
    header = json.loads(log.read_text().splitlines()[0])
    assert header["env_id"] == "StROL-Highway-v0" and header["extra"]["interact"]["blind"]
    assert (
        main(["replay", str(log), "--learners", "strol,gradient", "--out", str(tmp_path / "r")])
        == 0
    )


def test_key_presses_become_corrections_the_learner_sees(tmp_path):
    """Headless, the same loop: the keys' mean over a step times a_max is u_H; a step with no
    key is no correction; the robot replans (θ̂ moves); the panel is blind by default."""
    keys = iter([(1.0, 0.0), (0.0, 0.0), (0.0, 1.0), (0.0, 0.0), (-1.0, -1.0)] + [(0.0, 0.0)] * 9)
    panels = []
    path, info = run_drive(
        log=tmp_path / "d.jsonl",
        duration=4.0,
        realtime=False,
        window=False,
        keys=lambda: next(keys),
        on_step=lambda i, p: panels.append(p),
    )
    (ep,) = read_session(path).episodes
    u = np.array([c["u_h"] for c in ep.corrections])
    np.testing.assert_allclose(u, [[5.0, 0.0], [0.0, 0.02], [-5.0, -0.02]], atol=1e-7)
    assert info["corrections"] == 3 and not np.allclose(info["theta_hat"], ep.theta_hat0)
    assert all("theta_hat" not in line for p in panels for line in p)
    assert any("CORRECTION RECORDED" in line for line in panels[0])
    run_drive(
        log=tmp_path / "e.jsonl",
        duration=1.0,
        realtime=False,
        window=False,
        keys=lambda: (0.0, 0.0),
        blind=False,
        on_step=lambda i, p: panels.append(p),
    )
    assert any("theta_hat" in line for line in panels[-1])


def cli(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code)


def test_no_display_exits_2_with_one_line(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert cli(["interact", "--env", "highway", "--duration", "2"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and "display and a keyboard" in err[0]
    assert cli(["interact", "--env", "boat"]) == 2


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


@needs_x
def test_a_person_drags_the_arm_with_the_mouse_under_xvfb(tmp_path):
    """Ctrl + right-drag on the selected link, sent as X events: the log has the push, as a
    correction (above 15 N) or as a reflex event with its force (above 15 N: on v2 the brakes
    lock above 100 N, and also when a push would load a joint beyond its motor's torque or
    spin it to its speed limit, docs/study.md)."""
    log, lines = drag_session(tmp_path, DRAG, max_steps=160)
    corrections = [r for r in lines if r["type"] == "correction"]
    reflexes = [r for r in lines if r["type"] == "event" and r["kind"] == "reflex"]
    assert corrections or reflexes, "the drag left no trace in the log"
    for r in corrections:
        assert np.linalg.norm(np.array(r["trace"]["force"]), axis=1).max() > 15.0
        assert np.linalg.norm(r["u_h"]) > 0.0
    for r in reflexes:
        assert np.linalg.norm(r["force"]) > 15.0
    read_session(log)
