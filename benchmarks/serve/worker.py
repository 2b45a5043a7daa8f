"""One participant's session in a process of its own: the env at real time, frames out, the
person's keys and gamepad in.

The server starts :func:`run` per session (``multiprocessing``; a crash or a slow env touches
nobody else) with one end of a pipe. In: ``("input", {"keys": [...], "pad": {...} | None,
"n": int})`` (already checked by the server: :mod:`inputs`) and ``("stop", reason)``. Out:
``("frame", ack, jpeg)``, ``("panel", {...})``, then ``("end", {...})`` or ``("error", text)``.

The arm runs ``interact``'s own loop (:func:`run_interactive`) with :class:`WebViewer` as its
viewer: each sync turns the held keys (or the gamepad) into a push on the cup by the shared
mapping (:mod:`strol_gym.benchmarks.sessions.keys`: the camera's frame, a hand's ramp, capped
below the reflex unless "harder" is held), renders the scene offscreen when a frame is due and
sends the panel. The car runs ``drive``'s loop (:func:`run_drive`) with the keys from the page
and highway-env's own ``rgb_array`` frames. Both write the project's session log; a closed
connection ends the session with ``reason`` "connection closed".
"""

from __future__ import annotations

import copy
import io
import threading
import time
from typing import Any, NamedTuple

import mujoco
import numpy as np

from strol_gym.benchmarks.sessions import keys as keymap
from strol_gym.benchmarks.sessions.drive import run_drive
from strol_gym.benchmarks.sessions.interact import LOOKAT, draw_plan, run_interactive
from strol_gym.tasks.study import CONTROL_DT

FRAME_SIZE = (480, 360)
"""The arm's frames (width, height, px)."""
JPEG_QUALITY = 70
AZIMUTH, ELEVATION, DISTANCE = 150.0, -20.0, 2.2
"""The page's camera: ``interact``'s (the person's side of the table); the keys' frame."""
PANEL_SECONDS = 0.2
"""How often the panel goes to the page at most (s, wall clock)."""


class Inbox:
    """The pipe's reading side, in a thread: the latest keys and gamepad, and whether to stop."""

    def __init__(self, conn: Any) -> None:
        self.conn = conn
        self.keys: tuple[str, ...] = ()
        self.pad: keymap.Pad | None = None
        self.ack = 0
        self.stop_reason: str | None = None
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while self.stop_reason is None:
            try:
                kind, body = self.conn.recv()
            except (EOFError, OSError):
                self.stop_reason = "connection closed"
                return
            if kind == "stop":
                self.stop_reason = str(body)
            elif kind == "input":
                self.keys = tuple(body["keys"])
                pad = body.get("pad")
                self.pad = None if pad is None else keymap.Pad.of(pad["axes"], pad["buttons"])
                self.ack = int(body["n"])

    def arm_intent(self) -> keymap.Intent:
        intent = keymap.arm_intent(self.keys)
        if self.pad is not None:
            pad = keymap.pad_arm_intent(self.pad)
            if any(pad[:6]) or pad.harder:
                return pad
        return intent

    def car_intent(self) -> tuple[float, float]:
        accel, steer = keymap.car_intent(self.keys)
        if self.pad is not None:
            pa, ps = keymap.pad_car_intent(self.pad)
            accel, steer = (pa or accel), (ps or steer)
        return accel, steer


def jpeg(image: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image)).save(buf, "JPEG", quality=quality)
    return buf.getvalue()


def render_model(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` for drawing only: the collision meshes (2,300 faces) in place of the
    visual ones (134,000), no multisampling. Software rendering (EGL on a CPU) draws it in
    about 55 ms a frame instead of 630 ms (480 x 360; ``lab/notes/serve.md``)."""
    m = copy.deepcopy(model)
    mesh = m.geom_type == mujoco.mjtGeom.mjGEOM_MESH
    visual, collision = mesh & (m.geom_group == 0), mesh & (m.geom_group == 3)
    m.geom_group[visual] = 5  # a group the page's options leave hidden
    m.geom_group[collision] = 0
    m.geom_matid[collision] = -1
    m.geom_rgba[collision] = (0.85, 0.85, 0.88, 1.0)
    m.vis.quality.offsamples = 0
    return m


class PageDrag(NamedTuple):
    """A mouse perturbation's fields (``mjvPerturb``) as a viewer reports them: a page's is
    never active."""

    select: int
    active: int
    refselpos: np.ndarray
    refquat: np.ndarray
    localpos: np.ndarray


class WebViewer:
    """``interact``'s :class:`Viewer` for a page: pushes from the page's keys, frames to it."""

    show_target = False
    show_panel = True

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, inbox: Inbox, conn: Any,
                 fps: float) -> None:  # fmt: skip
        self.model, self.data, self.inbox, self.conn = model, data, inbox, conn
        self.period = 1.0 / fps
        self.end_reason: str | None = None
        self.push = keymap.ArmPush()
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "cup")
        self.body = int(model.site_bodyid[self.site])
        self.sim_time = float(data.time)
        self.wrench = keymap.ArmPush().step(keymap.Intent(), 0.0, AZIMUTH)
        w, h = FRAME_SIZE
        self.renderer = mujoco.Renderer(render_model(model), h, w)
        self.camera = mujoco.MjvCamera()
        self.camera.lookat[:] = LOOKAT
        self.camera.distance, self.camera.azimuth, self.camera.elevation = (
            DISTANCE,
            AZIMUTH,
            ELEVATION,
        )
        self.option = mujoco.MjvOption()
        self.plan: tuple[np.ndarray, np.ndarray | None] | None = None
        self.next_frame = 0.0
        self.next_panel = 0.0
        self.frames = 0

    def bind(self, study: Any) -> None:
        """The env's reflex (the keys' push stays below it unless "harder" is held)."""
        self.push = keymap.ArmPush(float(study.reflex_force), float(study.reflex_torque))

    def sync(self) -> None:
        """The held keys as a push on the cup, written where ``interact`` reads a mouse's:
        ``xfrc_applied`` of the cup's body, its torque shifted so that the wrench at the cup
        site is the push's (``read_perturbation`` moves it back)."""
        now = float(self.data.time)
        dt, self.sim_time = max(0.0, now - self.sim_time), now
        self.wrench = self.push.step(self.inbox.arm_intent(), dt, AZIMUTH)
        lever = self.data.xipos[self.body] - self.data.site_xpos[self.site]
        self.data.xfrc_applied[self.body, :3] = self.wrench.force
        self.data.xfrc_applied[self.body, 3:] = self.wrench.torque - np.cross(
            lever, self.wrench.force
        )
        clock = time.perf_counter()
        if clock >= self.next_frame:
            self.next_frame = max(self.next_frame + self.period, clock)
            self._frame()

    def _frame(self) -> None:
        ack = self.inbox.ack
        self.renderer.update_scene(self.data, self.camera, self.option)
        flags = self.renderer.scene.flags
        for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION):
            flags[flag] = 0
        if self.plan is not None:
            draw_plan(self.renderer.scene, self.plan[0], self.plan[1], append=True)
        self.conn.send(("frame", ack, jpeg(self.renderer.render())))
        self.frames += 1

    def is_running(self) -> bool:
        if self.inbox.stop_reason is not None:
            self.end_reason = self.inbox.stop_reason
            self.push.release()
            return False
        return True

    def set_texts(self, texts: Any) -> None:
        clock = time.perf_counter()
        if clock < self.next_panel:
            return
        self.next_panel = clock + PANEL_SECONDS
        self.conn.send(("panel", arm_panel(texts, self.wrench)))

    def draw_plan(self, points: np.ndarray, target: np.ndarray | None = None) -> None:
        self.plan = (np.array(points), None if target is None else np.array(target))

    # What a viewer that reports the keys themselves offers (the loop then pushes): the
    # page's keys, the camera's azimuth, the cup selected and no mouse drag.
    lost = ""
    want_cup = False

    def held_keys(self) -> frozenset[str]:
        return frozenset(self.inbox.keys)

    def azimuth(self) -> float:
        return AZIMUTH

    def select(self, body: int, localpos: np.ndarray) -> None:
        self.selected = (int(body), np.array(localpos, dtype=np.float64))

    def drag(self) -> PageDrag:
        """The cup selected, never dragged (a page has no mouse push)."""
        body, at = getattr(self, "selected", (self.body, np.zeros(3)))
        return PageDrag(body, 0, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), at)

    def close(self) -> None:
        self.renderer.close()


def arm_panel(texts: Any, wrench: keymap.Wrench) -> dict[str, Any]:
    """``interact``'s panel (``overlay``) for the page: its state rows and what to teach (its
    mouse instructions give way to the page's key help), its cues, and the push's size. The
    top-left text is read as "label: value" lines, or as two columns (labels, values)."""
    left = next((t for t in texts if t[1] == mujoco.mjtGridPos.mjGRID_TOPLEFT), None)
    right = next((t[2] for t in texts if t[1] == mujoco.mjtGridPos.mjGRID_TOPRIGHT), "")
    labels = left[2].split("\n") if left is not None else []
    values = (left[3] or "").split("\n") if left is not None else []
    values += [""] * (len(labels) - len(values))
    rows = [f"{a}: {b}" if a and b else a or b for a, b in zip(labels, values, strict=False)]
    state = rows[: rows.index("")] if "" in rows else rows
    teach = next((r[len("TEACH: ") :] for r in rows if r.startswith("TEACH: ")), "")
    return {
        "state": state,
        "teach": teach,
        "cues": [c for c in right.split("\n") if c],
        "push": round(wrench.size, 1),
        "torque": round(wrench.torque_size, 2),
        "harder": wrench.harder,
    }


def run(conn: Any, spec: dict[str, Any], log: str, fps: float) -> None:
    """A session in this process (see the module docstring); ``log`` is the server's path."""
    inbox = Inbox(conn)
    wall = time.perf_counter()
    try:
        if spec["kind"] == "arm":
            viewer: list[WebViewer] = []

            def factory(model: mujoco.MjModel, data: mujoco.MjData) -> WebViewer:
                viewer.append(WebViewer(model, data, inbox, conn, fps))
                return viewer[0]

            _, info = run_interactive(
                task=spec["task"],
                learner=spec["learner"],
                seed=spec["seed"],
                log=log,
                duration=spec["duration"],
                max_steps=round(spec["duration"] / CONTROL_DT),
                viewer_factory=factory,
                blind=True,
            )
            frames = viewer[0].frames if viewer else 0
        else:
            frames, info = _car(conn, inbox, spec, log)
        conn.send(
            (
                "end",
                {
                    "reason": _reason(log),
                    "corrections": int(info.get("corrections", 0)),
                    "real_time_factor": float(info.get("real_time_factor", float("nan"))),
                    "frames": frames,
                    # this process's CPU (every thread) per wall-clock second of the session
                    "cpu_share": time.process_time() / (time.perf_counter() - wall),
                },
            )
        )
    except Exception as e:  # the server reports it; the log keeps what was written
        conn.send(("error", f"{type(e).__name__}: {' '.join(str(e).split())[:300]}"))


def _car(conn: Any, inbox: Inbox, spec: dict[str, Any], log: str) -> tuple[int, dict[str, Any]]:
    sent = [0]

    def frame(image: np.ndarray) -> None:
        conn.send(("frame", inbox.ack, jpeg(image)))
        sent[0] += 1

    def panel(info: dict[str, Any], lines: list[str]) -> None:
        cues = [line for line in lines if line.startswith("CORRECTION")]
        teach = next((line[len("TEACH: ") :] for line in lines if line.startswith("TEACH: ")), "")
        conn.send(("panel", {"state": lines[:1], "teach": teach, "cues": cues}))

    _, info = run_drive(
        learner=spec["learner"],
        seed=spec["seed"],
        log=log,
        duration=spec["duration"],
        realtime=True,
        blind=True,
        keys=inbox.car_intent,
        window=False,
        on_step=panel,
        frames=frame,
        stop=lambda: inbox.stop_reason,
    )
    return sent[0], info


def _reason(log: str) -> str:
    """The ``end`` line's reason, as written."""
    import json

    from strol_gym.files import read_regular

    lines = read_regular(log, what="session log").splitlines()
    for line in reversed(lines):
        rec = json.loads(line)
        if rec.get("type") == "end":
            return str(rec.get("reason"))
    return "no end line"


__all__ = ["FRAME_SIZE", "Inbox", "WebViewer", "arm_panel", "jpeg", "render_model", "run"]
