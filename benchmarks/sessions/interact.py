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

import datetime as dt
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import mujoco
import numpy as np
from strol_gym.wrappers import OnlineLearningWrapper
from strol_gym.wrappers.session_log import SessionLogger

from strol_gym.envs.panda import PassiveViewer, has_display

NO_DISPLAY = (
    "interact needs a display (DISPLAY is not set): run it on a virtual one with "
    "`xvfb-run -a strol-bench interact ...`, or use the headless simulated users, "
    'gymnasium.make("StROL-Study-v0", human="nominal")'
)


class Viewer(Protocol):
    """What interact needs of ``mujoco.viewer.launch_passive``'s handle."""

    def sync(self) -> None: ...

    def is_running(self) -> bool: ...

    def set_texts(self, texts: Any) -> None: ...

    def close(self) -> None: ...


ViewerFactory = Callable[[mujoco.MjModel, mujoco.MjData], Viewer]


LOOKAT = (0.4, 0.0, 0.35)
"""Where the viewer's camera looks first (m, robot base frame): the pitcher, plate and arm."""


class _Passive(PassiveViewer):
    """The passive viewer (its ``close`` waits for the viewer's thread), UI panels hidden, the
    camera on the person's side of the table."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        super().__init__(model, data, show_left_ui=False, show_right_ui=False)
        with self.handle.lock():  # look at the workspace from the person's side of the table
            cam = self.handle.cam
            cam.lookat[:] = LOOKAT
            cam.distance, cam.azimuth, cam.elevation = 2.2, 150.0, -20.0

    def set_texts(self, texts: Any) -> None:
        self.handle.set_texts(texts)


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


def overlay(task: Any, info: dict[str, Any], felt: float) -> list[tuple]:
    """Viewer text: θ̂, correction time, features, the felt force (top left)."""
    theta = np.asarray(info["theta_hat"])
    phi = np.asarray(info["phi"])
    labels = ["time", "pushing", "corrections", "correction time"]
    values = [
        f"{info['time']:.1f} s",
        f"{felt:.1f} N" + (" (correcting)" if info["correction_active"] else ""),
        str(info["corrections"]),
        f"{info['correction_time']:.2f} s",
    ]
    for name, t, p in zip(task.feature_names, theta, phi, strict=True):
        labels.append(f"{name}: theta_hat / phi")  # the viewer's font is ASCII
        values.append(f"{t:+.3f} / {p:+.3f}")
    font = mujoco.mjtFontScale.mjFONTSCALE_150
    return [(font, mujoco.mjtGridPos.mjGRID_TOPLEFT, "\n".join(labels), "\n".join(values))]


def default_log_path() -> Path:
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    return Path("sessions") / f"session-{stamp}.jsonl"


def run_interactive(
    task: int = 1,
    learner: str = "strol",
    learner_kwargs: dict[str, Any] | None = None,
    seed: int = 20000,
    log: str | Path | None = None,
    duration: float = 120.0,
    max_steps: int | None = None,
    realtime: bool = True,
    viewer_factory: ViewerFactory = passive_viewer,
    env_kwargs: dict[str, Any] | None = None,
) -> tuple[Path, dict[str, Any]]:
    """Run one interactive session; returns the log's path and the last step's ``info``.

    Stops when the viewer closes, after ``duration`` s of simulated time, or after
    ``max_steps`` control steps. ``realtime`` paces steps to wall-clock time.
    """
    if isinstance(task, bool) or task not in (1, 2, 3):
        raise ValueError(f"task must be 1, 2 or 3, got {task!r}")
    if viewer_factory is passive_viewer and not has_display():
        raise ValueError(NO_DISPLAY)
    from strol_gym.tasks.study import CONTROL_DT

    path = Path(log) if log is not None else default_log_path()
    if path.exists():
        raise ValueError(f"log {path} exists; sessions are never overwritten")
    kwargs = {"task": task, "human": None, "duration": duration, **(env_kwargs or {})}
    base = gym.make("StROL-Study-v0", **kwargs)
    learning = OnlineLearningWrapper(base, learner, learner_kwargs=learner_kwargs)
    study = base.unwrapped
    site = mujoco.mj_name2id(study.model, mujoco.mjtObj.mjOBJ_SITE, "cup")
    viewer = viewer_factory(study.model, study.data)
    options = {"max_steps": max_steps, "realtime": realtime, "mode": "interactive"}
    env = SessionLogger(learning, path, extra={"interact": options})
    try:
        _, info = env.reset(seed=seed)
        info.update(correction_active=False, corrections=0, correction_time=0.0, time=0.0)
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        steps, reason, ended = 0, "viewer closed", False
        t_next = time.perf_counter()
        while viewer.is_running():
            if max_steps is not None and steps >= max_steps:
                reason = "max_steps"
                break
            study.data.xfrc_applied[:] = 0.0  # what is left there is the env's own push
            viewer.sync()  # zeroes xfrc_applied, then writes the mouse's perturbation
            force, torque = read_perturbation(study.model, study.data, site, study.task.oriented)
            study.hold_wrench(force, torque)
            _, _, terminated, truncated, info = env.step(action)
            steps += 1
            felt = float(np.linalg.norm(info["wrench"][:3]))
            viewer.set_texts(overlay(study.task, info, felt))
            if terminated or truncated:  # SessionLogger wrote the end line
                ended = True
                break
            if realtime:
                t_next += CONTROL_DT
                time.sleep(max(0.0, t_next - time.perf_counter()))
        if not ended:
            env.end_session(reason)
    finally:
        viewer.close()
        env.close()
    return path, info


# ---------------------------------------------------------------------- CLI (strol-bench interact)
def add_parser(sub: Any) -> None:
    from strol_gym.benchmarks.args import plugin_option

    p = sub.add_parser(
        "interact",
        help="push the study arm yourself in MuJoCo's viewer; the robot learns (needs a display)",
        description="Open MuJoCo's passive viewer on StROL-Study-v0 (no simulated user). Push "
        "the arm with Ctrl + right-drag (double-click a link first to select it): a push above "
        "15 N is a correction; the learner updates and the robot replans. The session is "
        "logged for strol-bench replay. Without a display: xvfb-run -a strol-bench interact.",
    )
    p.add_argument("--task", default="1", help="study Task: 1, 2 or 3 (default 1)")
    p.add_argument("--learner", default="strol", help="registered name or module:attr (strol)")
    p.add_argument("--learner-kwargs", default=None, help="JSON, e.g. '{\"lam\": 0.5}'")
    p.add_argument("--seed", type=int, default=20000, help="θ̂0's seed (default 20000)")
    p.add_argument("--log", default=None, help="session log (default sessions/session-TIME.jsonl)")
    p.add_argument("--duration", type=float, default=120.0, help="simulated seconds (120)")
    p.add_argument("--max-steps", type=int, default=None, help="stop after N control steps")
    p.add_argument("--fast", action="store_true", help="do not pace the steps to wall-clock time")
    plugin_option(p)


def command(args: Any, parser: Any) -> int:
    import json

    from strol_gym.benchmarks.args import check_learner_names

    if args.task not in ("1", "2", "3"):
        raise ValueError(f"--task must be 1, 2 or 3, got {args.task!r}")
    if not has_display():  # before anything is built
        raise ValueError(NO_DISPLAY)
    check_learner_names([args.learner])
    kwargs = None
    if args.learner_kwargs:
        try:
            kwargs = json.loads(args.learner_kwargs)
        except json.JSONDecodeError as e:
            raise ValueError(f"--learner-kwargs must be a JSON object ({e})") from None
        if not isinstance(kwargs, dict):
            raise ValueError("--learner-kwargs must be a JSON object")
    if args.max_steps is not None and args.max_steps < 1:
        raise ValueError(f"--max-steps must be >= 1, got {args.max_steps}")
    path, info = run_interactive(
        task=int(args.task),
        learner=args.learner,
        learner_kwargs=kwargs,
        seed=args.seed,
        log=args.log,
        duration=args.duration,
        max_steps=args.max_steps,
        realtime=not args.fast,
    )
    theta = ", ".join(f"{t:+.3f}" for t in info["theta_hat"])
    print(f"{info['corrections']} correction(s), {info['correction_time']:.2f} s of pushing")
    print(f"final θ̂ = ({theta}); session log: {path}")
    print(f"replay it: strol-bench replay {path} --learners strol,gradient")
    return 0


__all__ = ["NO_DISPLAY", "Viewer", "passive_viewer", "read_perturbation", "run_interactive"]
