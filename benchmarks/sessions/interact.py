"""``strol-bench interact``: a person pushes the study arm in MuJoCo's viewer; the robot learns.

The pipeline is the simulated users' own: each control step the viewer's perturbation (Ctrl +
right-drag on the arm) is read *after* ``viewer.sync()`` (``sync`` zeroes ``xfrc_applied`` and
then writes the mouse's force), handed to the env with ``hold_wrench``, and the env steps:
15 N threshold, u_H, the learner's update in ``OnlineLearningWrapper``, replanning. Every
session is logged (``session_log``) and can be replayed with ``strol-bench replay``.

The viewer sits behind :class:`Viewer` (``sync``, ``is_running``, ``set_texts``, ``close``), so
tests inject a fake that writes a wrench the way the real one does.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import gymnasium as gym
import mujoco
import numpy as np

from strol_gym import checks
from strol_gym.benchmarks.sessions import keys
from strol_gym.benchmarks.sessions.person import (
    Pace,
    default_log_path,
    ended_words,
    sigterm_stops,
    stop_reason,
)
from strol_gym.envs.panda.model import PassiveViewer, has_display
from strol_gym.envs.study.env import StudyEnv
from strol_gym.wrappers import OnlineLearningWrapper
from strol_gym.wrappers.session_log import SessionLogger

NO_DISPLAY = (
    "interact needs a display (DISPLAY is not set): run it on a virtual one with "
    "`xvfb-run -a strol-bench interact ...`, or use the headless simulated users, "
    'gymnasium.make("StROL-Study-v2") (its default person, the fitted population)'
)


class DragLike(Protocol):
    """The viewer's mouse perturbation as the person left it (``mjvPerturb``'s fields)."""

    @property
    def select(self) -> int:
        """The selected body (0 or less: nothing; a drag then moves the camera)."""
        ...

    @property
    def active(self) -> int:
        """``mjtPertBit`` bits: translate (Ctrl + right-drag), rotate (Ctrl + left-drag)."""
        ...

    @property
    def refselpos(self) -> np.ndarray:
        """Where the drag wants the selected point (m, world)."""
        ...

    @property
    def refquat(self) -> np.ndarray:
        """The orientation the drag wants of the body's inertial frame."""
        ...

    @property
    def localpos(self) -> np.ndarray:
        """The selected point in the body's frame (m)."""
        ...


class Drag(NamedTuple):
    """A :class:`DragLike` read from MuJoCo's viewer (or written by a script)."""

    select: int
    active: int
    refselpos: np.ndarray
    refquat: np.ndarray
    localpos: np.ndarray


class Viewer(Protocol):
    """What interact needs of ``mujoco.viewer.launch_passive``'s handle."""

    def sync(self) -> None: ...

    def is_running(self) -> bool: ...

    def set_texts(self, texts: Any) -> None: ...

    def draw_plan(self, points: np.ndarray, target: np.ndarray | None = None) -> None: ...

    def close(self) -> None: ...

    def drag(self) -> DragLike:
        """The mouse's perturbation now."""
        ...

    def select(self, body: int, localpos: np.ndarray) -> None:
        """Select ``body`` at ``localpos`` (its frame), as a double-click on it does."""
        ...

    def held_keys(self) -> frozenset[str]:
        """The keys held now (``keys.key_name`` spelling)."""
        ...

    def azimuth(self) -> float:
        """The camera's azimuth (degrees, MuJoCo's convention)."""
        ...

    show_target: bool
    """Whether the person asked to see the plan for θ* (a key); the front end reads it."""
    want_cup: bool
    """Whether the person asked for the cup to be selected again (a key)."""
    lost: str
    """Why the window went away without closing ("" while it is there): "X error"."""


ViewerFactory = Callable[[mujoco.MjModel, mujoco.MjData], Viewer]


LOOKAT = (0.35, 0.05, 0.62)
"""Where the viewer's camera looks first (m, robot base frame): the pitcher, plate and arm."""


RENDER_NICE = 10
"""The niceness of the viewer's drawing threads: on one core the physics comes first."""


def yield_to_physics() -> None:
    """Lower the priority of every thread of this process but the caller's (the viewer's
    render thread and software rendering's workers, started with the viewer): where they share
    a core with the physics, the physics gets it when it wakes. Linux only (nice is per thread
    there); elsewhere, or without the right, nothing changes."""
    me = threading.get_native_id()
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        return
    for tid in tids:
        if tid != me:
            try:
                os.setpriority(os.PRIO_PROCESS, tid, RENDER_NICE)
            except OSError:
                pass


GLFW_NAMES: dict[int, str] = {
    **{code: chr(code).lower() for code in range(ord("A"), ord("Z") + 1)},
    32: " ",
    262: "arrowright",
    263: "arrowleft",
    264: "arrowdown",
    265: "arrowup",
    266: "pageup",
    267: "pagedown",
    268: "home",
    340: "shift",
    344: "shift",
}
"""GLFW key codes -> the key names of ``keys`` (a browser's ``KeyboardEvent.key``, lower case)."""
GRABBED = frozenset(keys.ARM_KEYS)
"""Keys the viewer never sees: MuJoCo binds every letter to a rendering flag (W: wireframe),
the arrows and Page Up to its history and selection."""
_ALIVE: list[Any] = []
"""The key filters handed to GLFW: never freed while a window may call them."""


class KeyGrab:
    """The arm's keys, read from the viewer's window (GLFW) and kept from the viewer.

    The passive viewer offers only a callback on key presses, run on its thread; the first one
    finds the window (``glfwGetCurrentContext``) and puts this filter in front of the viewer's
    own key handler: it records presses and releases of every named key and passes on all
    but :data:`GRABBED`. The first key itself reached the viewer: a letter toggled a flag, so
    it is sent once more (the flag toggles back)."""

    def __init__(self) -> None:
        self.held: set[str] = set()
        self._prev: Any = None
        self.window: Any = None

    def on_first_key(self, keycode: int) -> None:
        """From the viewer's key callback (its thread, its window's context current)."""
        if self.window is not None:
            return
        import glfw

        window = glfw.get_current_context()
        if not window:
            return
        # pyGLFW's own callback type and library: the viewer's C code calls glfw through the
        # same library (mujoco.viewer hands it pyGLFW's handle)
        py_glfw: Any = glfw  # its private parts have no type stubs
        callback = py_glfw._GLFWkeyfun(self._on_key)
        _ALIVE.append(callback)
        self._prev = py_glfw._glfw.glfwSetKeyCallback(window, callback)
        self.window = window
        name = GLFW_NAMES.get(keycode, "")
        if name in GRABBED:
            self.held.add(name)
            if len(name) == 1 and self._prev:  # a letter's flag: toggle it back
                self._prev(window, keycode, 0, glfw.PRESS, 0)
                self._prev(window, keycode, 0, glfw.RELEASE, 0)

    def _on_key(self, window: Any, key: int, scancode: int, action: int, mods: int) -> None:
        try:
            name = GLFW_NAMES.get(key)
            if name is not None:
                if action == 1:  # GLFW_PRESS (2, a repeat, changes nothing)
                    self.held.add(name)
                elif action == 0:
                    self.held.discard(name)
            if name not in GRABBED and self._prev:
                self._prev(window, key, scancode, action, mods)
        except Exception:  # an exception must not cross into GLFW's C code
            pass


def watch_x_errors(on_error: Callable[[str], None], on_lost: Callable[[], None]) -> None:
    """Where the display is X11: an X error (the window destroyed under the viewer, as closing
    it without a window manager does) calls ``on_error("X error")`` instead of Xlib's default,
    which exits the process; the connection lost calls ``on_lost()``, which must end the
    process (Xlib exits after it). Elsewhere nothing changes."""
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("X11")
    if name is None or not os.environ.get("DISPLAY"):
        return
    try:
        lib = ctypes.CDLL(name)
    except OSError:
        return
    error_type = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)
    lost_type = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)

    def error(display: Any, event: Any) -> int:
        on_error("X error")
        return 0

    def lost(display: Any) -> int:
        on_lost()
        return 0

    handlers = (error_type(error), lost_type(lost))
    _ALIVE.extend(handlers)
    lib.XSetErrorHandler.argtypes = [error_type]
    lib.XSetErrorHandler.restype = ctypes.c_void_p
    lib.XSetIOErrorHandler.argtypes = [lost_type]
    lib.XSetIOErrorHandler.restype = ctypes.c_void_p
    lib.XSetErrorHandler(handlers[0])
    lib.XSetIOErrorHandler(handlers[1])


class _Passive(PassiveViewer):
    """The passive viewer (its ``close`` waits for the viewer's thread), UI panels hidden, the
    camera on the person's side of the table, the arm's keys read (``KeyGrab``).

    The panel goes to the viewer from a thread of its own: ``handle.set_texts`` waits for the
    viewer's next frame (0.56 s a call measured under Xvfb with software rendering, one core
    at load ~16), which in the physics loop held the arm at 0.09x real time. The physics only
    leaves the latest panel; the thread shows it when the viewer can."""

    on_lost: Callable[[], None] | None = None
    """Set by the session: ends it when the X connection is lost (then the process exits)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.show_target = False
        self.show_panel = True
        self.want_cup = False
        self.lost = ""
        self.grab = KeyGrab()
        watch_x_errors(self._x_error, self._x_lost)
        super().__init__(
            model, data, show_left_ui=False, show_right_ui=False, key_callback=self._key
        )
        with self.handle.lock():  # look at the workspace from the person's side of the table
            cam = self.handle.cam
            cam.lookat[:] = LOOKAT
            cam.distance, cam.azimuth, cam.elevation = 2.2, 150.0, -20.0
        yield_to_physics()
        self._latest: Any = None
        self._fresh = threading.Event()
        self._stop = False
        self._panel = threading.Thread(target=self._show_panels, daemon=True)
        self._panel.start()

    def _x_error(self, what: str) -> None:
        self.lost = what

    def _x_lost(self) -> None:
        self.lost = "X connection lost"
        if self.on_lost is not None:
            self.on_lost()
        os._exit(0)

    def set_texts(self, texts: Any) -> None:
        self.texts = texts  # the panel as last shown (the viewer has no getter)
        self._latest = texts
        self._fresh.set()

    def _show_panels(self) -> None:
        while not self._stop:
            if self._fresh.wait(0.1):
                self._fresh.clear()
                if self._stop:
                    break
                self.handle.set_texts(self._latest)

    def close(self, timeout: float = 10.0) -> None:
        self._stop = True
        self._fresh.set()
        self._panel.join(timeout=timeout)
        super().close(timeout)

    def _key(self, keycode: int) -> None:  # the viewer's thread: only flip a flag
        self.grab.on_first_key(keycode)
        if GLFW_NAMES.get(keycode) == keys.CUP_KEY:
            self.want_cup = True
        elif keycode == TARGET_KEY:
            self.show_target = not self.show_target
        elif keycode == PANEL_KEY:
            self.show_panel = not self.show_panel

    def held_keys(self) -> frozenset[str]:
        return frozenset(self.grab.held)

    def azimuth(self) -> float:
        return float(self.handle.cam.azimuth)

    def drag(self) -> Drag:
        with self.handle.lock():
            p = self.handle.perturb
            return Drag(
                int(p.select),
                int(p.active),
                np.array(p.refselpos, dtype=np.float64),
                np.array(p.refquat, dtype=np.float64),
                np.array(p.localpos, dtype=np.float64),
            )

    def select(self, body: int, localpos: np.ndarray) -> None:
        with self.handle.lock():
            p = self.handle.perturb
            p.select, p.skinselect, p.flexselect = body, -1, -1
            p.localpos[:] = localpos

    def draw_plan(self, points: np.ndarray, target: np.ndarray | None = None) -> None:
        """The plan's waypoints (cup positions, m) as small spheres in the user scene, and the
        plan for θ* (``target``) in green."""
        with self.handle.lock():
            draw_plan(self.handle.user_scn, points, target)


VIEWER_KEYS = (
    "every letter A-Z, ` \\ ; ' , / (visual and rendering flags), 0-5 and Shift+0-5 (groups), "
    "Space, + - =, Left/Right, Tab/Shift+Tab, [ ], Esc, Page Up, Backspace, F1-F7, "
    "Ctrl+A/C/D/L/M/P/Q, Alt+letter (the panels' sections)"
)
"""MuJoCo's passive viewer's own keys (MuJoCo 3.x: ``mujoco.mjVISSTRING`` and
``mujoco.mjRNDSTRING`` bind every letter; the rest is simulate's help and UI shortcuts): ours
are function keys it leaves free, and the push keys it never sees (``KeyGrab``)."""
TARGET_KEY = 297
"""F8 (GLFW key code): show or hide the plan for θ* (T, our old key, also toggled MuJoCo's
transparency)."""
PANEL_KEY = 298
"""F9 (GLFW key code): show or hide the panel (the scene is never hidden by it)."""
PLAN_RGBA = np.array([0.1, 0.55, 1.0, 0.7], dtype=np.float32)
TARGET_RGBA = np.array([0.1, 0.8, 0.2, 0.7], dtype=np.float32)
PLAN_RADIUS = 0.012


def draw_plan(
    scene: mujoco.MjvScene,
    points: np.ndarray,
    target: np.ndarray | None = None,
    append: bool = False,
) -> None:
    """Replace ``scene``'s geoms (``append``: add to them) with one sphere per waypoint of
    ``points`` (blue), then of ``target`` (green), as many as fit."""
    layers = [(points, PLAN_RGBA)] + ([] if target is None else [(target, TARGET_RGBA)])
    n = scene.ngeom if append else 0
    for pts, rgba in layers:
        for p in np.asarray(pts, dtype=np.float64).reshape(-1, 3)[: scene.maxgeom - n]:
            mujoco.mjv_initGeom(
                scene.geoms[n],
                mujoco.mjtGeom.mjGEOM_SPHERE,
                np.array([PLAN_RADIUS, 0.0, 0.0]),
                p,
                np.eye(3).ravel(),
                rgba,
            )
            n += 1
    scene.ngeom = n


def passive_viewer(model: mujoco.MjModel, data: mujoco.MjData) -> Viewer:
    """MuJoCo's passive viewer (needs a display)."""
    if not has_display():
        raise ValueError(NO_DISPLAY)
    return _Passive(model, data)


DRAG_STIFFNESS = 400.0
"""N per m of drag: the force of a mouse drag is this times how far (m, in the scene) the
dragged point is from where the drag wants it; a 10 cm drag pushes 40 N, the simulated users'
push (the env's own stiffness, 300-400 N/m, is a hand's on the cup)."""
DRAG_TURN_STIFFNESS = 30.0
"""N m per rad of a rotating drag (Ctrl + left-drag): 0.2 rad (11°) turns with 6 N m."""


def drag_wrench(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    drag: DragLike,
    site: int,
    oriented: bool,
    limits: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """The mouse's push as a wrench at the cup, from the drag's length in metres: F =
    ``DRAG_STIFFNESS`` × (where the drag wants the point − where it is), at most ``limits[0]``
    N; a rotating drag's torque from the angle between the orientation it wants and the body's,
    at most ``limits[1]`` N m. At the cup: τ = τ_drag + (p − p_cup) × F. Task 1's corrections
    are positions: its torque is dropped (the env would count ‖τ‖ / 0.1 m towards the
    threshold)."""
    force, torque = np.zeros(3), np.zeros(3)
    b = drag.select
    if b <= 0 or b >= model.nbody or not drag.active:
        return force, torque
    point = data.xpos[b] + data.xmat[b].reshape(3, 3) @ drag.localpos
    if drag.active & int(mujoco.mjtPertBit.mjPERT_TRANSLATE):
        force = _capped(DRAG_STIFFNESS * (drag.refselpos - point), limits[0])
    if not oriented:
        return force, torque
    if drag.active & int(mujoco.mjtPertBit.mjPERT_ROTATE):
        body = np.zeros(4)
        mujoco.mju_mulQuat(body, data.xquat[b], model.body_iquat[b])
        inverse, diff, turn = np.zeros(4), np.zeros(4), np.zeros(3)
        mujoco.mju_negQuat(inverse, body)
        mujoco.mju_mulQuat(diff, drag.refquat, inverse)
        mujoco.mju_quat2Vel(turn, diff, 1.0)
        torque = _capped(DRAG_TURN_STIFFNESS * turn, limits[1])
    return force, torque + np.cross(point - data.site_xpos[site], force)


def _capped(v: np.ndarray, top: float) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v * (top / n) if n > top else v


FEATURE_WORDS = {
    "pitcher": ("close to the pitcher", "away from the pitcher"),
    "plate": ("close to the plate", "away from the plate"),
    "table": ("low, near the table", "high above the table"),
    "upright": ("upright", "tilted"),
}
"""Per study feature: what a positive and a negative weight ask of the cup (φ are negated
distances, the cup's height and its tilt)."""


def teach_words(
    feature_names: Any,
    theta_star: np.ndarray,
    phrases: dict[str, tuple[str, str]] | None = None,
    lead: str = "carry the cup ",
) -> str:
    """θ* in words, strongest weight first; weights below 0.1 in size are left out.
    ``phrases``: per feature, what a positive and a negative weight ask (the study's cup by
    default)."""
    phrases = FEATURE_WORDS if phrases is None else phrases
    order = np.argsort(-np.abs(theta_star))
    words = []
    for i in order:
        if abs(theta_star[i]) < 0.1:
            continue
        name = feature_names[i]
        pos, neg = phrases.get(name, (f"more {name}", f"less {name}"))
        words.append(pos if theta_star[i] > 0 else neg)
    return lead + ", ".join(words) if words else "anything goes (θ* is about 0)"


HELP = (
    ("KEYS", "W/S A/D E/Q push away/back, left/right, up/down;"),
    ("", "I/K J/L U/O tilt/turn/roll; Shift harder; Home: cup"),
    ("MOUSE", "Ctrl + right-drag: {drag:.0f} N per 10 cm of drag"),
    ("COUNTS", ">{threshold:.0f} N a correction; >{reflex:.0f} N {joint}brakes"),
    ("PLAN", "blue; F8: yours in green; F9: hide this"),
    ("END", "close the window; time is up at {duration:.0f} s"),
)
"""The panel's help: (label, words) rows (the viewer draws at most 500 characters a column:
state and help share the panel's two columns)."""
OVERLAY_CHARS = 500
"""The most characters MuJoCo's viewer draws of one overlay column (``mjMAXOVERLAY``)."""
CUE_SECONDS = 2.0
"""How long (simulated s) the panel shows a recorded correction or a reflex."""
TOO_HARD = "TOO HARD: the arm braked, no correction"
JOINT_LIMIT = "(or a joint's limit) "
"""The help's words where the version also brakes on a joint's torque (v2)."""
PANEL_HIDDEN = "F9: show the panel"
NOTHING_SELECTED = "NOTHING SELECTED: a drag moves the camera; Home selects the cup"


def overlay(
    task: Any,
    info: dict[str, Any],
    felt: float,
    *,
    teach: str = "",
    threshold: float = 15.0,
    reflex_force: float = 100.0,
    joint_reflex: bool = False,
    last_correction: tuple[float, np.ndarray] | None = None,
    last_reflex: tuple[float, float] | None = None,
    rtf: float | None = None,
    blind: bool = True,
    panel: bool = True,
    push: keys.Wrench | None = None,
    selected: str = "the cup",
    duration: float = 120.0,
) -> list[tuple]:
    """Viewer text (ASCII: the viewer's font has no θ or φ) in the top corners only, so the
    table, the pitcher and the plate stay in view: state, how to push and what to teach top
    left, in two columns (labels, words; ``panel`` false: one line saying how to show it),
    cues and the real-time factor top right. ``blind`` (a participant's view) leaves θ̂ and φ
    out (else they follow the cues); the log keeps them.
    ``joint_reflex``: the arm also brakes on a push a joint cannot bear (v2), so a reflex may
    come below ``reflex_force`` and the panel says so. ``push``: the keys' (or gamepad's)
    push this step; ``selected``: what a drag pushes ("" for nothing: the cue says so)."""
    font = mujoco.mjtFontScale.mjFONTSCALE_100
    grid = mujoco.mjtGridPos
    texts: list[tuple] = []
    extra: list[str] = []  # θ̂ and φ (not blind): below the cues
    if panel:
        key_push = "none"
        if push is not None and (push.size > 0 or push.torque_size > 0):
            key_push = f"{push.size:.0f} N, {push.torque_size:.1f} N m"
            key_push += " (HARDER)" if push.harder else ""
        rows = [
            ("time", f"{info['time']:.1f} s of {duration:.0f} s"),
            ("pushing", f"{felt:.1f} N" + (" (correcting)" if info["correction_active"] else "")),
            ("key push", key_push),
            ("drag pushes", selected or "nothing"),
            ("corrections", str(info["corrections"])),
            ("correction time", f"{info['correction_time']:.2f} s"),
            ("", ""),
        ]
        words: dict[str, Any] = {"threshold": threshold, "reflex": reflex_force}
        words["duration"] = duration
        words |= {"joint": JOINT_LIMIT if joint_reflex else "", "drag": DRAG_STIFFNESS * 0.1}
        rows += [(label, text.format(**words)) for label, text in HELP]
        rows.append(("TEACH", teach))
        labels, values = zip(*rows, strict=True)
        column = "\n".join(values)[:OVERLAY_CHARS]  # the viewer would cut it anyway
        texts.append((font, grid.mjGRID_TOPLEFT, "\n".join(labels), column))
        if not blind:
            theta = np.asarray(info["theta_hat"])
            phi = np.asarray(info["phi"])
            for name, t, p in zip(task.feature_names, theta, phi, strict=True):
                extra.append(f"{name}: theta_hat {t:+.3f} / phi {p:+.3f}")
    else:
        texts.append((font, grid.mjGRID_TOPLEFT, PANEL_HIDDEN, ""))
    cues = []
    if last_reflex is not None and info["time"] - last_reflex[0] <= CUE_SECONDS:
        why = f" > {reflex_force:.0f} N" if last_reflex[1] > reflex_force else ": a joint's limit"
        cues.append(f"{TOO_HARD} ({last_reflex[1]:.0f} N{why})")
    elif felt > reflex_force:
        cues.append(f"{TOO_HARD} ({felt:.0f} N > {reflex_force:.0f} N)")
    elif info.get("braked", False):
        cues.append("BRAKED: let go; the arm recovers once you stop pushing")
    elif felt > threshold:
        cues.append(f"PUSH COUNTS: {felt:.0f} N > {threshold:.0f} N")
    if last_correction is not None and info["time"] - last_correction[0] <= CUE_SECONDS:
        u_h = ", ".join(f"{v:+.3f}" for v in last_correction[1])
        cues.append(f"CORRECTION RECORDED: u_H = ({u_h})")
    if not selected:
        cues.append(NOTHING_SELECTED)
    if rtf is not None:
        cues.append(f"real-time factor {rtf:.2f}")
        if rtf < 0.9:
            cues.append("WARNING: below 0.9, the arm runs slower than real time")
    cues += extra
    if cues:
        texts.append((font, grid.mjGRID_TOPRIGHT, "\n".join(cues), ""))
    return texts


def panel_text(texts: list[tuple]) -> str:
    """The top-left panel of ``overlay``'s texts as plain lines, "label words" (what a person
    reads across its two columns)."""
    labels, words = texts[0][2].split("\n"), (texts[0][3] or "").split("\n")
    words += [""] * (len(labels) - len(words))
    return "\n".join(f"{a} {b}".strip() for a, b in zip(labels, words, strict=False))


class RealTimeFactor:
    """Simulated seconds per wall-clock second over the last ``window`` steps."""

    def __init__(self, window: int = 20) -> None:
        self.window = window
        self.marks: list[tuple[float, float]] = []

    def update(self, sim_time: float) -> float | None:
        self.marks.append((sim_time, time.perf_counter()))
        del self.marks[: -self.window - 1]
        (s0, w0), (s1, w1) = self.marks[0], self.marks[-1]
        return None if len(self.marks) < 3 or w1 <= w0 else (s1 - s0) / (w1 - w0)


def session_env(
    task: int,
    learner: str | Any = "strol",
    learner_kwargs: dict[str, Any] | None = None,
    env_kwargs: dict[str, Any] | None = None,
) -> OnlineLearningWrapper:
    """The env and learner a person meets: ``strol-bench study``'s own (its default version's
    env id and Task, hence its ĝ), with no simulated person (``person=None``). With a
    ``duration`` in ``env_kwargs`` the step limit is set from it (the registered one, 60 s,
    would end the session first)."""
    from strol_gym.benchmarks.engine.conditions import env_preset
    from strol_gym.envs.study.versions import LATEST
    from strol_gym.tasks.study import CONTROL_DT

    # strol-bench study's default preset (experiments.study.study_env(task), which this layer
    # may not import): the latest version's, its Task and ĝ; tests/test_interact.py checks
    # the two agree.
    preset = env_preset(f"study{task}-{LATEST.name}")
    kwargs = {**(preset.make_kwargs or {}), "person": None, **(env_kwargs or {})}
    if "duration" in kwargs and "max_episode_steps" not in kwargs:
        kwargs["max_episode_steps"] = max(1, math.ceil(kwargs["duration"] / CONTROL_DT - 1e-9))
    base = gym.make(preset.env_id, **kwargs)
    return OnlineLearningWrapper(base, learner, learner_kwargs=learner_kwargs)


PadSource = Callable[[], keys.Pad | None]
"""A gamepad read once per control step (None: none connected)."""


class _Ending:
    """The ``end`` line, written once whoever ends the session (the loop, or the viewer's
    thread when the X connection is lost), with the session's reason and simulated time."""

    def __init__(self, env: SessionLogger) -> None:
        self.env = env
        self.info: dict[str, Any] = {}
        self.reason = ""
        self._lock = threading.Lock()

    def __call__(self, reason: str, interrupted: bool = False) -> bool:
        with self._lock:
            if self.reason:
                return False
            self.reason = reason
            self.env.end_session(
                reason, self.info, interrupted=interrupted, reflexes=self.info.get("reflexes")
            )
            return True


def run_interactive(
    task: int = 1,
    learner: str = "strol",
    learner_kwargs: dict[str, Any] | None = None,
    seed: int = 20000,
    log: str | Path | None = None,
    duration: float = 120.0,
    max_steps: int | None = None,
    realtime: bool = True,
    viewer_factory: ViewerFactory | None = None,
    env_kwargs: dict[str, Any] | None = None,
    blind: bool = True,
    pad: PadSource | None = None,
    sizes: keys.PushSizes | None = None,
) -> tuple[Path, dict[str, Any]]:
    """Run one interactive session; returns the log's path and the last step's ``info``
    (with ``real_time_factor``: simulated over wall-clock seconds for the whole session, and
    ``end_reason``).

    Ends when time is up (``duration`` simulated s: the env's step limit), after
    ``max_steps`` control steps, when the viewer's window closes or goes away (an X error), or
    on Ctrl-C / SIGTERM (``interrupted``); the ``end`` line says which. ``realtime`` paces
    steps to wall-clock time. ``blind`` hides θ̂ and φ from the panel (the log keeps them).
    The person pushes with the mouse (a drag, its force from its length in metres), the keys
    and ``pad`` (``keys``: the push's size from ``sizes``).
    """
    if isinstance(task, bool) or task not in (1, 2, 3):
        raise ValueError(f"task must be 1, 2 or 3, got {task!r}")
    if viewer_factory is None:  # looked up now, so a front end can wrap it
        viewer_factory = passive_viewer
    if viewer_factory is passive_viewer and not has_display():
        raise ValueError(NO_DISPLAY)
    from strol_gym.tasks.study import CONTROL_DT

    path = Path(log) if log is not None else default_log_path()
    if path.exists():
        raise ValueError(f"log {path} exists; sessions are never overwritten")
    learning = session_env(
        task, learner, learner_kwargs, {"duration": duration, **(env_kwargs or {})}
    )
    study = learning.unwrapped
    assert isinstance(study, StudyEnv)  # the study's preset is a StudyEnv
    site = mujoco.mj_name2id(study.model, mujoco.mjtObj.mjOBJ_SITE, "cup")
    cup_body = int(study.model.site_bodyid[site])
    viewer = viewer_factory(study.model, study.data)
    bind = getattr(viewer, "bind", None)
    if bind is not None:  # a front end that needs the env itself (its reflex, its Task)
        bind(study)
    options: dict[str, Any] = {"max_steps": max_steps, "realtime": realtime, "blind": blind}
    options |= {"mode": "interactive", "duration": duration}
    env = SessionLogger(learning, path, extra={"interact": options}, auto_end=False)
    ending = _Ending(env)
    reflex_force = float(getattr(study, "reflex_force", math.inf))
    look: dict[str, Any] = {  # what the panel says whatever the step
        "teach": teach_words(study.task.feature_names, study.task.theta_star),
        "threshold": float(study.force_threshold),
        "reflex_force": reflex_force,
        "joint_reflex": bool(study.version.torque_reflex),
        "blind": blind,
        "duration": duration,
    }
    hand = keys.ArmPush(
        reflex_force, float(getattr(study, "reflex_torque", math.inf)), sizes or keys.PushSizes()
    )
    oriented = bool(study.task.oriented)
    info: dict[str, Any] = {}
    pace = Pace(CONTROL_DT, realtime)

    def lost() -> None:  # the viewer's thread, the X connection gone: the process ends next
        if ending("window closed (X connection lost)"):
            print(ended_words(ending.reason, float(ending.info.get("time", 0.0))), flush=True)
        env.close()

    if isinstance(viewer, _Passive):
        viewer.on_lost = lost
    try:
        with sigterm_stops():
            _, info = env.reset(seed=seed)
            info.update(correction_active=False, corrections=0, correction_time=0.0, time=0.0)
            ending.info = info
            viewer.select(cup_body, study.model.site_pos[site].copy())  # the cup, selected
            action = np.zeros(
                checks.space_shape("action_space", env.action_space), dtype=np.float32
            )
            try:
                info = _session_loop(
                    env,
                    study,
                    viewer,
                    ending,
                    pace,
                    action,
                    hand,
                    pad,
                    site,
                    oriented,
                    look,
                    max_steps,
                )
            except KeyboardInterrupt as e:
                ending(stop_reason(e), interrupted=True)
                info = {**ending.info, "interrupted": True}
    finally:
        viewer.close()
        env.close()
    return path, {**info, "real_time_factor": pace.factor, "end_reason": ending.reason}


def _session_loop(
    env: SessionLogger,
    study: StudyEnv,
    viewer: Viewer,
    ending: _Ending,
    pace: Pace,
    action: np.ndarray,
    hand: keys.ArmPush,
    pad: PadSource | None,
    site: int,
    oriented: bool,
    look: dict[str, Any],
    max_steps: int | None,
) -> dict[str, Any]:
    """The control loop of :func:`run_interactive`; returns the last ``info``."""
    from strol_gym.tasks.study import CONTROL_DT

    info = ending.info
    last_correction: tuple[float, np.ndarray] | None = None
    last_reflex: tuple[float, float] | None = None
    drawn: tuple[int, int] | None = None
    target: np.ndarray | None = None
    rtf = RealTimeFactor()
    selected = -1
    mouse = (np.zeros(3), np.zeros(3))
    push = hand.step(keys.Intent(), 0.0, 0.0)
    while True:
        if viewer.lost:
            ending(f"window closed ({viewer.lost})")
            break
        if not viewer.is_running():  # a front end may say why it closed (a page's connection)
            ending(getattr(viewer, "end_reason", None) or "window closed")
            break
        if max_steps is not None and pace.steps >= max_steps:
            ending("max_steps")
            break
        synced = pace.sync_now()
        held = viewer.held_keys()
        intent = keys.arm_intent(held)
        state = pad() if pad is not None else None
        if state is not None:
            intent = _stronger(intent, keys.pad_arm_intent(state))
        push = hand.step(intent, CONTROL_DT, viewer.azimuth())
        if synced:
            study.data.xfrc_applied[:] = 0.0  # what is left there is the env's own push
            viewer.sync()  # the viewer writes its own push there: ours replaces it
            study.data.xfrc_applied[:] = 0.0
            if getattr(viewer, "want_cup", False):  # the cup key
                viewer.want_cup = False
                viewer.select(int(study.model.site_bodyid[site]), study.model.site_pos[site])
            drag = viewer.drag()
            if drag.select != selected:
                selected = drag.select
                name = mujoco.mj_id2name(study.model, mujoco.mjtObj.mjOBJ_BODY, selected)
                env.writer.event(
                    kind="select",
                    time=info["time"],
                    step=pace.steps,
                    body=name if selected > 0 else None,
                )
            mouse = drag_wrench(
                study.model, study.data, drag, site, oriented, hand.ceiling(intent.harder)
            )
        key_torque = push.torque if oriented else np.zeros(3)
        study.hold_wrench(mouse[0] + push.force, mouse[1] + key_torque)  # to the next step
        obs, _, terminated, truncated, info = env.step(action)
        ending.info = info
        felt = float(np.linalg.norm(info["wrench"][:3]))
        if info.get("reflex", False):  # the person's push tripped the arm's brakes
            last_reflex = (info["time"], felt)
            env.writer.event(
                kind="reflex",
                time=info["time"],
                step=pace.steps,
                force=np.asarray(info["wrench"][:3]),
                torque=np.asarray(info["wrench"][3:]),
                reflex_force=look["reflex_force"],
            )
        if info["is_correction"]:
            last_correction = (info["time"], np.asarray(info["correction"]))
        factor = rtf.update(info["time"])
        if synced:
            want = bool(getattr(viewer, "show_target", False))
            if want and target is None:  # θ*'s plan from where the cup is now
                start = np.asarray(obs["state"], dtype=np.float64)[None]
                target = study.task.plan(study.task.theta_star[None], start)[0][:, :3]
            elif not want:
                target = None
            key = (id(study.plan_waypoints), id(target))
            if key != drawn:  # a new plan (or leg), or θ*'s plan shown or hidden
                drawn = key
                viewer.draw_plan(study.plan_waypoints[:, :3], target)
            texts = overlay(
                study.task,
                info,
                felt,
                **look,
                last_correction=last_correction,
                last_reflex=last_reflex,
                rtf=factor,
                panel=bool(getattr(viewer, "show_panel", True)),
                push=push,
                selected=_body_words(study.model, selected, site),
            )
            viewer.set_texts(texts)
        pace.wait()
        if info.get("unstable"):
            ending("unstable (the simulation diverged)")
            break
        if terminated or truncated:
            ending("time up")
            break
    return info


def _stronger(a: keys.Intent, b: keys.Intent) -> keys.Intent:
    """Per axis, the larger in size of two intents (the keys and a gamepad together)."""
    axes = {n: max(getattr(a, n), getattr(b, n), key=abs) for n in keys.AXES}
    return keys.Intent(**axes, harder=a.harder or b.harder)


def _body_words(model: mujoco.MjModel, body: int, site: int) -> str:
    """What a drag pushes, for the panel ("" for nothing)."""
    if body <= 0:
        return ""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body {body}"
    return "the cup" if body == int(model.site_bodyid[site]) else name


__all__ = [
    "NO_DISPLAY",
    "Drag",
    "KeyGrab",
    "Pace",
    "Viewer",
    "drag_wrench",
    "draw_plan",
    "overlay",
    "panel_text",
    "passive_viewer",
    "run_interactive",
    "session_env",
    "teach_words",
]
