"""strol-bench interact under Xvfb with a scripted person: MuJoCo's real passive viewer, a
drag of the cup read after each ``sync`` (as the mouse's perturbation is), the
panel read back through the front end, the plan's spheres found in the viewer's user scene, and
Ctrl-C (a real SIGINT) ending a session cleanly."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from strol_gym.benchmarks.sessions.interact import teach_words
from strol_gym.tasks.study import StudyTask1V2
from strol_gym.wrappers.session_log import read_session

pytestmark = pytest.mark.skipif(
    shutil.which("xvfb-run") is None, reason="xvfb-run is not installed (apt-get install xvfb)"
)

PUSH_START, PUSH_STEPS, FORCE = 10, 20, 30.0

DRIVER = """
import json, os, sys
from pathlib import Path

import mujoco
import numpy as np
from strol_gym.benchmarks.sessions import interact
from strol_gym.benchmarks.cli import main

out_path, ready_path = Path(sys.argv[1]), Path(sys.argv[2])
START, STEPS, FORCE = (int(sys.argv[3]), int(sys.argv[4]), float(sys.argv[5]))
out = {"texts": [], "plans": []}


class ScriptedPerson(interact._Passive):
    # The real viewer; during the push the drag's point is put where the mouse would leave
    # it for FORCE N along +y (the cup is selected at the start).

    def __init__(self, model, data):
        super().__init__(model, data)
        self.model, self.data, self.k, self.pushing = model, data, 0, False
        self.cup = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "cup")

    def sync(self):
        super().sync()
        self.pushing = START <= self.k < START + STEPS
        self.k += 1
        if self.k == START + STEPS + 10:
            ready_path.write_text(str(os.getpid()))

    def drag(self):
        d = super().drag()
        if not self.pushing:
            return d
        ref = self.data.site_xpos[self.cup] + np.array([0.0, FORCE, 0.0]) / interact.DRAG_STIFFNESS
        translate = int(mujoco.mjtPertBit.mjPERT_TRANSLATE)
        return interact.Drag(d.select, translate, ref, d.refquat, d.localpos)

    def set_texts(self, texts):
        super().set_texts(texts)
        out["texts"].append([interact.panel_text(self.texts)] + [t[2] for t in self.texts[1:]])

    def draw_plan(self, points, target=None):
        super().draw_plan(points, target)
        site = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, "cup")
        with self.handle.lock():
            scn = self.handle.user_scn
            geoms = [scn.geoms[i].pos.tolist() for i in range(scn.ngeom)]
        out["plans"].append(
            {"points": np.asarray(points).tolist(), "geoms": geoms,
             "cup": self.data.site_xpos[site].tolist()}
        )


interact.passive_viewer = ScriptedPerson
try:
    code = main(sys.argv[6:])
finally:
    out_path.write_text(json.dumps(out))
sys.exit(code)
"""


def _start(tmp_path: Path, *argv: str) -> tuple[subprocess.Popen, Path, Path]:
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    out, ready = tmp_path / "out.json", tmp_path / "ready"
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", sys.executable, str(driver)]
    cmd += [str(out), str(ready), str(PUSH_START), str(PUSH_STEPS), str(FORCE), *argv]
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    return proc, out, ready


def test_scripted_person_sees_the_panel_the_plan_and_the_correction_cue(tmp_path):
    log = tmp_path / "s.jsonl"
    proc, out, _ = _start(
        tmp_path, "interact", "--task", "1", "--max-steps", "60", "--fast", "--log", str(log)
    )
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr[-3000:]
    seen = json.loads(out.read_text())
    session = read_session(log)
    (ep,) = session.episodes
    (c,) = ep.corrections

    task = StudyTask1V2()
    how = seen["texts"][0][0]
    assert "Ctrl + right-drag" in how
    assert how.endswith("TEACH " + teach_words(task.feature_names, task.theta_star))
    cues = ["\n".join(t[1:]) for t in seen["texts"]]
    assert [k for k, t in enumerate(cues) if "PUSH COUNTS: 30 N" in t] == list(
        range(PUSH_START, PUSH_START + PUSH_STEPS)
    )
    u_h = "CORRECTION RECORDED: u_H = (" + ", ".join(f"{v:+.3f}" for v in c["u_h"]) + ")"
    assert any(u_h in t for t in cues)
    assert any("real-time factor" in t for t in cues)

    # The plan's spheres sit at the plan's waypoints, in the frame of the cup itself.
    first = seen["plans"][0]
    points, geoms = np.array(first["points"]), np.array(first["geoms"])
    assert len(geoms) == len(points) > 2
    np.testing.assert_allclose(geoms, points, atol=1e-6)  # the scene stores float32
    np.testing.assert_allclose(points[0], first["cup"], atol=0.02)  # it starts at the cup
    x0 = json.loads(log.read_text().splitlines()[1])["x0"]
    # v2's planner walks the Task's reachable set itself (no executed box): that is drawn
    planned = task.plan(ep.theta_hat0[None], np.array(x0)[None])[0]
    planned = planned[:, :3]
    # the log's x0 is the float32 obs; v2's walk inside the reachable set carries its rounding
    np.testing.assert_allclose(points, planned, atol=5e-4)
    assert "replay it" in stdout


def test_ctrl_c_ends_the_session_with_130_one_line_and_an_end_line(tmp_path):
    log = tmp_path / "s.jsonl"
    proc, _, ready = _start(tmp_path, "interact", "--task", "1", "--log", str(log))
    deadline = time.monotonic() + 240
    while not ready.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert ready.exists(), proc.communicate(timeout=30)[1][-3000:]
    time.sleep(0.2)
    os.kill(int(ready.read_text()), signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr[-3000:]
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("interrupted:"), stderr
    assert "resume" not in stderr + stdout
    assert "correction(s)" in stdout and "final θ̂" in stdout  # the summary
    end = json.loads(log.read_text().splitlines()[-1])
    assert end["type"] == "end" and end["interrupted"] is True and end["corrections"] == 1
