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
from typing import Any, Protocol

import gymnasium as gym
import mujoco
import numpy as np

from strol_gym import checks
from strol_gym.benchmarks.sessions.person import Pace, default_log_path
from strol_gym.envs.panda.model import PassiveViewer, has_display
from strol_gym.envs.study.env import StudyEnv
from strol_gym.wrappers import OnlineLearningWrapper
from strol_gym.wrappers.session_log import SessionLogger

NO_DISPLAY = (
    "interact needs a display (DISPLAY is not set): run it on a virtual one with "
    "`xvfb-run -a strol-bench interact ...`, or use the headless simulated users, "
    'gymnasium.make("StROL-Study-v1", human="nominal")'
)


class Viewer(Protocol):
    """What interact needs of ``mujoco.viewer.launch_passive``'s handle."""

    def sync(self) -> None: ...

    def is_running(self) -> bool: ...

    def set_texts(self, texts: Any) -> None: ...

    def draw_plan(self, points: np.ndarray, target: np.ndarray | None = None) -> None: ...

    def close(self) -> None: ...

    show_target: bool
    """Whether the person asked to see the plan for θ* (a key); the front end reads it."""


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


class _Passive(PassiveViewer):
    """The passive viewer (its ``close`` waits for the viewer's thread), UI panels hidden, the
    camera on the person's side of the table.

    The panel goes to the viewer from a thread of its own: ``handle.set_texts`` waits for the
    viewer's next frame (0.56 s a call measured under Xvfb with software rendering, one core
    at load ~16), which in the physics loop held the arm at 0.09x real time. The physics only
    leaves the latest panel; the thread shows it when the viewer can."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.show_target = False
        self.show_panel = True
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
        if keycode == TARGET_KEY:
            self.show_target = not self.show_target
        elif keycode == PANEL_KEY:
            self.show_panel = not self.show_panel

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
are function keys it leaves free."""
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


def read_perturbation(
    model: mujoco.MjModel, data: mujoco.MjData, site: int, oriented: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The person's push as a wrench at the cup, then cleared from ``xfrc_applied``.

    The viewer writes its perturbation into ``xfrc_applied`` of the selected body (force at
    the body's centre of mass, and torque). Summed over bodies and moved to the cup site:
    F = Σ F_b, τ = Σ τ_b + (c_b − p_cup) × F_b. Task 1's corrections are positions: its torque
    is dropped (the env would count ‖τ‖ / 0.1 m towards the threshold). The perturbation is
    cleared so that the env's own application of it (on the hand) is the only one.
    """
    xfrc = data.xfrc_applied
    force = xfrc[:, :3].sum(axis=0)
    torque = np.zeros(3)
    if oriented:
        lever = data.xipos - data.site_xpos[site]
        torque = xfrc[:, 3:].sum(axis=0) + np.cross(lever, xfrc[:, :3]).sum(axis=0)
    xfrc[:] = 0.0
    return force.copy(), torque


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


INSTRUCTIONS = (
    "HOW: double-click a link of the arm to select it,",
    "then Ctrl + right-drag to push it.",
    "A push above {threshold:.0f} N is a correction; above {reflex:.0f} N the arm brakes",
    "{joint}(too hard: no correction). Blue dots: the robot's plan;",
    "F8: the plan for what you teach (green). F9: hide this panel.",
    "Close the window to end.",
)
CUE_SECONDS = 2.0
"""How long (simulated s) the panel shows a recorded correction or a reflex."""
TOO_HARD = "TOO HARD: the arm braked, no correction"
JOINT_LIMIT = "or sooner where a joint cannot bear the push "
"""The instructions' words where the version also brakes on a joint's torque (v2)."""
PANEL_HIDDEN = "F9: show the panel"


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
) -> list[tuple]:
    """Viewer text (ASCII: the viewer's font has no θ or φ) in the top corners only, so the
    table, the pitcher and the plate stay in view: state, how to push and what to teach top
    left (``panel`` false: one line saying how to show it), cues and the real-time factor top
    right. ``blind`` (a participant's view) leaves θ̂ and φ out; the log keeps them.
    ``joint_reflex``: the arm also brakes on a push a joint cannot bear (v2), so a reflex may
    come below ``reflex_force`` and the panel says so."""
    font = mujoco.mjtFontScale.mjFONTSCALE_100
    grid = mujoco.mjtGridPos
    texts: list[tuple] = []
    if panel:
        labels = ["time", "pushing", "corrections", "correction time"]
        values = [
            f"{info['time']:.1f} s",
            f"{felt:.1f} N" + (" (correcting)" if info["correction_active"] else ""),
            str(info["corrections"]),
            f"{info['correction_time']:.2f} s",
        ]
        if not blind:
            theta = np.asarray(info["theta_hat"])
            phi = np.asarray(info["phi"])
            for name, t, p in zip(task.feature_names, theta, phi, strict=True):
                labels.append(f"{name}: theta_hat / phi")
                values.append(f"{t:+.3f} / {p:+.3f}")
        how = "\n".join(INSTRUCTIONS).format(
            threshold=threshold, reflex=reflex_force, joint=JOINT_LIMIT if joint_reflex else ""
        )
        state = [f"{k}: {v}" for k, v in zip(labels, values, strict=True)]
        lines = [*state, "", *how.split("\n"), "TEACH: " + teach]
        texts.append((font, grid.mjGRID_TOPLEFT, "\n".join(lines), ""))
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
    if rtf is not None:
        cues.append(f"real-time factor {rtf:.2f}")
        if rtf < 0.9:
            cues.append("WARNING: below 0.9, the arm runs slower than real time")
    if cues:
        texts.append((font, grid.mjGRID_TOPRIGHT, "\n".join(cues), ""))
    return texts


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
    env id and Task, hence its ĝ), with no simulated person (``human=None``)."""
    from strol_gym.benchmarks.engine.conditions import env_preset

    # strol-bench study's default preset (experiments.study.study_env(task), which this layer
    # may not import): v2, its Task and ĝ; tests/test_interact.py checks the two agree.
    preset = env_preset(f"study{task}-v2")
    kwargs = {**(preset.make_kwargs or {}), "human": None, **(env_kwargs or {})}
    base = gym.make(preset.env_id, **kwargs)
    return OnlineLearningWrapper(base, learner, learner_kwargs=learner_kwargs)


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
) -> tuple[Path, dict[str, Any]]:
    """Run one interactive session; returns the log's path and the last step's ``info``
    (with ``real_time_factor``: simulated over wall-clock seconds for the whole session).

    Stops when the viewer closes, after ``duration`` s of simulated time, or after
    ``max_steps`` control steps. ``realtime`` paces steps to wall-clock time. ``blind`` hides
    θ̂ and φ from the panel (the log keeps them).
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
    viewer = viewer_factory(study.model, study.data)
    bind = getattr(viewer, "bind", None)
    if bind is not None:  # a front end that needs the env itself (its reflex, its Task)
        bind(study)
    options = {"max_steps": max_steps, "realtime": realtime, "mode": "interactive", "blind": blind}
    env = SessionLogger(learning, path, extra={"interact": options})
    teach = teach_words(study.task.feature_names, study.task.theta_star)
    threshold = float(study.force_threshold)
    reflex_force = float(getattr(study, "reflex_force", math.inf))
    joint_reflex = bool(study.version.torque_reflex)
    info: dict[str, Any] = {}
    pace = Pace(CONTROL_DT, realtime)
    try:
        _, info = env.reset(seed=seed)
        info.update(correction_active=False, corrections=0, correction_time=0.0, time=0.0)
        action = np.zeros(checks.space_shape("action_space", env.action_space), dtype=np.float32)
        reason, ended = "viewer closed", False
        last_correction: tuple[float, np.ndarray] | None = None
        last_reflex: tuple[float, float] | None = None
        drawn: tuple[int, int] | None = None
        target: np.ndarray | None = None
        rtf = RealTimeFactor()
        pace = Pace(CONTROL_DT, realtime)
        try:
            while viewer.is_running():
                if max_steps is not None and pace.steps >= max_steps:
                    reason = "max_steps"
                    break
                synced = pace.sync_now()
                if synced:
                    study.data.xfrc_applied[:] = 0.0  # what is left there is the env's own push
                    viewer.sync()  # zeroes xfrc_applied, then writes the mouse's perturbation
                    force, torque = read_perturbation(
                        study.model, study.data, site, study.task.oriented
                    )
                    study.hold_wrench(force, torque)  # held until the next sync
                obs, _, terminated, truncated, info = env.step(action)
                felt = float(np.linalg.norm(info["wrench"][:3]))
                if info.get("reflex", False):  # the person's push tripped the arm's brakes
                    last_reflex = (info["time"], felt)
                    env.writer.event(
                        kind="reflex",
                        time=info["time"],
                        step=pace.steps,
                        force=np.asarray(info["wrench"][:3]),
                        torque=np.asarray(info["wrench"][3:]),
                        reflex_force=reflex_force,
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
                        teach=teach,
                        threshold=threshold,
                        reflex_force=reflex_force,
                        joint_reflex=joint_reflex,
                        last_correction=last_correction,
                        last_reflex=last_reflex,
                        rtf=factor,
                        blind=blind,
                        panel=bool(getattr(viewer, "show_panel", True)),
                    )
                    viewer.set_texts(texts)
                if terminated or truncated:  # SessionLogger wrote the end line
                    ended = True
                    break
                pace.wait()
        except KeyboardInterrupt:
            env.end_session("interrupted", info, interrupted=True)
            info = {**info, "interrupted": True}
            ended = True
        if not ended:  # a front end may say why it closed (e.g. the page's connection)
            env.end_session(getattr(viewer, "end_reason", None) or reason)
    finally:
        viewer.close()
        env.close()
    return path, {**info, "real_time_factor": pace.factor}


# ---------------------------------------------------------------------- CLI (strol-bench interact)
def add_parser(sub: Any) -> None:
    import argparse

    from strol_gym.benchmarks.args import plugin_option

    p = sub.add_parser(
        "interact",
        help="push the study arm yourself in MuJoCo's viewer; the robot learns (needs a display)",
        description="Open MuJoCo's passive viewer on the study env strol-bench study runs (its "
        "Task and learner, no simulated user). Push the arm with Ctrl + right-drag (double-click "
        "a link first to select it): a push above 15 N is a correction (above the 100 N reflex, "
        "or on v2 sooner where a joint cannot bear the push, the arm brakes and nothing "
        "counts); the learner updates and the robot replans. F8: the "
        "plan for theta*; F9: hide or show the panel. The session is logged for strol-bench "
        "replay. Without a display: xvfb-run -a strol-bench interact.",
    )
    p.add_argument(
        "--env",
        default="robot",
        help="robot (push the study arm in MuJoCo's viewer, default) or highway (drive the "
        "human car with the arrow keys in highway-env's window)",
    )
    p.add_argument("--task", default="1", help="study Task: 1, 2 or 3 (default 1; robot only)")
    p.add_argument("--learner", default="strol", help="registered name or module:attr (strol)")
    p.add_argument("--learner-kwargs", default=None, help="JSON, e.g. '{\"lam\": 0.5}'")
    p.add_argument("--seed", type=int, default=20000, help="θ̂0's seed (default 20000)")
    p.add_argument("--log", default=None, help="session log (default sessions/session-TIME.jsonl)")
    p.add_argument("--duration", type=float, default=120.0, help="simulated seconds (120)")
    p.add_argument("--max-steps", type=int, default=None, help="stop after N control steps")
    p.add_argument("--fast", action="store_true", help="do not pace the steps to wall-clock time")
    p.add_argument(
        "--blind",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="hide theta_hat and phi from the panel (default: a participant never sees them; "
        "the log keeps them); --no-blind for the experimenter",
    )
    plugin_option(p)


def command(args: Any, parser: Any) -> int:
    import json
    import math

    from strol_gym.benchmarks.args import check_learner_names

    if args.task not in ("1", "2", "3"):
        raise ValueError(f"--task must be 1, 2 or 3, got {args.task!r}")
    check_learner_names([args.learner])
    kwargs = None
    if args.learner_kwargs:
        try:
            kwargs = json.loads(args.learner_kwargs)
        except (ValueError, RecursionError) as e:
            raise ValueError(f"--learner-kwargs must be a JSON object ({e})") from None
        if not isinstance(kwargs, dict):
            raise ValueError("--learner-kwargs must be a JSON object, e.g. '{\"lam\": 0.5}'")
    if args.max_steps is not None and args.max_steps < 1:
        raise ValueError(f"--max-steps must be an integer >= 1, got {args.max_steps}")
    if not math.isfinite(args.duration) or not 0 < args.duration <= 86_400:
        raise ValueError(f"--duration must be in (0, 86400] simulated seconds, got {args.duration}")
    if args.log is not None and Path(args.log).exists():
        raise ValueError(f"--log {args.log} exists; sessions are never overwritten")
    if args.env not in ("robot", "highway"):
        raise ValueError(f"--env must be robot or highway, got {args.env!r}")
    if args.env == "highway":
        from strol_gym.benchmarks.sessions.drive import NO_DISPLAY_HIGHWAY, run_drive

        if not has_display():
            raise ValueError(NO_DISPLAY_HIGHWAY)
        duration = args.duration if args.max_steps is None else args.max_steps * 0.5
        path, info = run_drive(
            learner=args.learner,
            learner_kwargs=kwargs,
            seed=args.seed,
            log=args.log,
            duration=duration,
            realtime=not args.fast,
            blind=args.blind,
        )
        return _summary(path, info)
    if not has_display():  # after the arguments, before anything is built
        raise ValueError(NO_DISPLAY)
    path, info = run_interactive(
        task=int(args.task),
        learner=args.learner,
        learner_kwargs=kwargs,
        seed=args.seed,
        log=args.log,
        duration=args.duration,
        max_steps=args.max_steps,
        realtime=not args.fast,
        blind=args.blind,
    )
    return _summary(path, info)


def _summary(path: Path, info: dict[str, Any]) -> int:
    """The session's last lines on the terminal; 130 after Ctrl-C."""
    import sys

    print(f"real-time factor {info['real_time_factor']:.2f} (simulated s per wall-clock s)")
    if "theta_hat" in info:
        theta = ", ".join(f"{t:+.3f}" for t in info["theta_hat"])
        pushing = info.get("correction_time")
        print(
            f"{info['corrections']} correction(s)"
            + ("" if pushing is None else f", {pushing:.2f} s of pushing")
        )
        print(f"final θ̂ = ({theta}); session log: {path}")
    print(f"replay it: strol-bench replay {path} --learners strol,gradient")
    if info.get("interrupted"):
        print(f"interrupted: the session ended and its log is complete ({path})", file=sys.stderr)
        return 130
    return 0


__all__ = [
    "NO_DISPLAY",
    "Pace",
    "Viewer",
    "draw_plan",
    "overlay",
    "passive_viewer",
    "read_perturbation",
    "run_interactive",
    "session_env",
    "teach_words",
]
