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

START = """
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
"""
"""The person's script starts the session (its arguments) and waits for its window."""

PERSON = (
    START
    + """
sleep 1.2
xdotool keydown Up; sleep 1.2; xdotool keyup Up
sleep 1.2
xdotool keydown Left; sleep 1.2; xdotool keyup Left
wait $pid
"""
)


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


CRASH = (
    START
    + """sleep 1.0
# full throttle, then steer right into the robot car's lane as well, until the session ends
xdotool keydown Up; sleep 1.3; xdotool keydown Right
wait $pid
status=$?
xdotool keyup Right keyup Up
exit $status
"""
)


@needs_x
def test_a_crash_ends_the_drive_and_says_so_under_xvfb(tmp_path):
    """Driven into the robot car (xdotool keys): the session ends at once, the console says the
    cars collided, the end line's reason says so with the simulated time, exit 0."""
    log = tmp_path / "crash.jsonl"
    script = tmp_path / "crash.sh"
    script.write_text(CRASH)
    env = {k: v for k, v in os.environ.items() if k != "SDL_VIDEODRIVER"}
    cli = [sys.executable, "-m", "strol_gym.benchmarks.cli", "interact", "car"]
    cli += ["--duration", "30", "--log", str(log)]
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", "bash", str(script), str(log), *cli]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=180, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    end = json.loads(log.read_text().splitlines()[-1])
    assert end["type"] == "end" and end["reason"] == "crash: the cars collided", end
    assert 0 < end["sim_time"] < 30.0 and end["sim_time"] == pytest.approx(end["steps"] * 0.5)
    assert "THE CARS COLLIDED" in done.stdout and "session ended: crash" in done.stdout


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


ARM_PERSON = """
import json, math, subprocess, sys, time
from pathlib import Path

import numpy as np

log, mode, camera = Path(sys.argv[1]), sys.argv[2], json.loads(sys.argv[3])
proc = subprocess.Popen(sys.argv[4:])


def records():
    return [json.loads(t) for t in log.read_text().splitlines()] if log.exists() else []


def wait_for(test, seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end and proc.poll() is None:
        if any(test(r) for r in records()):
            return True
        time.sleep(0.1)
    return False


def xdo(*argv):
    return subprocess.run(["xdotool", *map(str, argv)], check=True, capture_output=True,
                          text=True, timeout=120).stdout


def selected(*bodies):
    return lambda r: r["type"] == "event" and r["kind"] == "select" and r["body"] in bodies


# the physics runs (its first sync logs the cup's selection) and the window is on screen
assert wait_for(selected("panda0_link7"), 240), "the session never started"
wid = xdo("search", "--sync", "--onlyvisible", "--name", "^MuJoCo").split()[0]
geo = dict(kv.split("=") for kv in xdo("getwindowgeometry", "--shell", wid).split())
x0, y0, w, h = (int(geo[k]) for k in ("X", "Y", "WIDTH", "HEIGHT"))


def on_screen(point):
    # where a point of the scene is in the window: MuJoCo's free camera as interact sets it
    az, el = math.radians(camera["azimuth"]), math.radians(camera["elevation"])
    fwd = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    eye = np.array(camera["lookat"]) - camera["distance"] * fwd
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    d = np.asarray(point) - eye
    t = math.tan(math.radians(camera["fovy"]) / 2)
    nx, ny = d @ right / (d @ fwd) / (t * w / h), d @ up / (d @ fwd) / t
    return round(x0 + (nx + 1) / 2 * w), round(y0 + (1 - ny) / 2 * h)


def double_click_until(where, *bodies):
    # a person double-clicks again when the first did not take
    for _ in range(6):
        seen = len(records())
        xdo("mousemove", *where)
        xdo("click", "--repeat", 2, "--delay", 60, 1)
        end = time.monotonic() + 6
        while time.monotonic() < end:
            if any(selected(*bodies)(r) for r in records()[seen:]):
                return
            time.sleep(0.1)
    raise AssertionError(f"double-clicks at {where} never selected {bodies}")


cup = next(r for r in records() if r["type"] == "episode")["x0"][:3]
if mode == "keys":
    xdo("mousemove", x0 + w // 2, y0 + h // 2)  # no window manager: keys go under the pointer
    for _ in range(3):  # W held 3 s (again if the push never reached the arm)
        # the viewer reads the keys when it draws a frame: slow in software, on a busy machine
        xdo("keydown", "w")
        time.sleep(3.0)
        xdo("keyup", "w")
        if wait_for(lambda r: r["type"] == "correction", 10):
            break
    xdo("windowclose", wid)  # no window manager: the window destroyed under the viewer
elif mode == "click":
    double_click_until(on_screen([0.0, 0.0, 0.1]), "panda0_link0", "panda0_link1")  # the base
    double_click_until((x0 + 10, y0 + 10), None)  # the sky: nothing selected
    for _ in range(6):  # Home: the cup again (pressed again if it did not take)
        seen = len(records())
        xdo("key", "Home")
        if wait_for(lambda r: r in records()[seen:] and selected("panda0_link7")(r), 6):
            break
    for _ in range(3):  # a Ctrl + right-drag (again if it left no trace: a person would)
        xdo("mousemove", x0 + w // 2, y0 + h // 2, "keydown", "ctrl", "mousedown", 3)
        for _ in range(20):
            xdo("mousemove_relative", "--", 3, -2)
            time.sleep(0.05)
        time.sleep(3.0)  # the viewer reads the mouse when it draws a frame (slow in software)
        xdo("mouseup", 3, "keyup", "ctrl")
        if wait_for(lambda r: r["type"] == "correction" or r.get("kind") == "reflex", 10):
            break
    xdo("windowclose", wid)
sys.exit(proc.wait(timeout=240))
"""


def arm_session(tmp_path: Path, mode: str, *argv: str) -> tuple[Path, list[dict], str]:
    """`strol-bench interact` on the arm under Xvfb while a person (``ARM_PERSON``) acts in
    ``mode``: the log's path, its records and the console's output."""
    from strol_gym.benchmarks.sessions.interact import LOOKAT

    log = tmp_path / "arm.jsonl"
    (tmp_path / "person.py").write_text(ARM_PERSON)
    camera = {"azimuth": 150.0, "elevation": -20.0, "distance": 2.2, "lookat": list(LOOKAT)}
    camera["fovy"] = 45.0
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    run = [sys.executable, "-m", "strol_gym.benchmarks.cli", "interact", "arm", "--task", "1"]
    run += [*argv, "--log", str(log)]
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", sys.executable]
    cmd += [str(tmp_path / "person.py"), str(log), mode, json.dumps(camera), *run]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=400, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    return log, [json.loads(t) for t in log.read_text().splitlines()], done.stdout


@needs_x
def test_a_person_pushes_with_a_key_and_closes_the_window_under_xvfb(tmp_path):
    """W held in the viewer's window (xdotool): one correction whose u_H points within 30
    degrees of W's direction (away from the camera, laid flat); then the window destroyed under
    the viewer (no window manager: an X error) ends the session with its reason and exit 0."""
    from strol_gym.benchmarks.sessions.keys import camera_axes

    log, lines, out = arm_session(tmp_path, "keys", "--duration", "100")
    (c,) = [r for r in lines if r["type"] == "correction"]
    away = camera_axes(150.0)[:, 1]
    cos = np.dot(c["u_h"], away) / np.linalg.norm(c["u_h"])
    assert np.degrees(np.arccos(min(1.0, cos))) < 30.0, c["u_h"]
    end = lines[-1]
    assert end["type"] == "end" and end["reason"].startswith("window closed"), end
    assert end["steps"] > 0 and end["sim_time"] == pytest.approx(end["steps"] * 0.05)
    assert "session ended: window closed" in out
    assert lines[0]["extra"]["interact"]["duration"] == 100.0
    read_session(log)


@needs_x
def test_a_person_selects_the_cup_and_drags_it_with_the_mouse_under_xvfb(tmp_path):
    """Real double-clicks (xdotool): on the arm's base the base is selected, on the sky nothing
    is (each logged; the panel says a drag would move the camera); Home selects the cup again;
    then Ctrl + right-drag: the log has the push,
    as a correction (above 15 N) or as a reflex event with its force (on v2 the brakes lock above
    100 N, and also when a push would load a joint beyond its motor's torque or spin it to its
    speed limit, docs/study.md)."""
    log, lines, _ = arm_session(tmp_path, "click")
    corrections = [r for r in lines if r["type"] == "correction"]
    reflexes = [r for r in lines if r["type"] == "event" and r["kind"] == "reflex"]
    assert corrections or reflexes, "the drag left no trace in the log"
    for r in corrections:
        assert np.linalg.norm(np.array(r["trace"]["force"]), axis=1).max() > 15.0
        assert np.linalg.norm(r["u_h"]) > 0.0
    for r in reflexes:
        assert np.linalg.norm(r["force"]) > 15.0
    picked = [r["body"] for r in lines if r["type"] == "event" and r["kind"] == "select"]
    assert picked[0] == "panda0_link7" and picked[1] in ("panda0_link0", "panda0_link1")
    assert picked[2:4] == [None, "panda0_link7"], picked
    assert lines[-1]["reason"].startswith("window closed")
    read_session(log)
    with pytest.raises(ValueError, match="task must be 1, 2 or 3"):
        from strol_gym.benchmarks.sessions.interact import run_interactive

        run_interactive(task=5)
