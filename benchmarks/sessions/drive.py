"""``strol-bench interact --env highway``: a person drives the human car; the robot car learns.

The person drives the blue (human) car with the arrow keys (or WASD, or a gamepad) in
highway-env's own window (pygame); what the keys mean is ``keys``' (``car_intent``, the same
mapping a browser uses). Each env step (0.5 s, the Highway Task's ``dt``) the keys are read
every ``POLL_SECONDS`` and averaged (``keys.car_correction``): u_H = a_max ⊙ (mean(up − down),
mean(right − left)), a_max = ``task.action_bound`` (5 m/s², 0.02 rad). Holding Up for the
whole step is +a_max acceleration, for half of it +a_max / 2; Right steers towards the right
lane (highway-env's y grows to the driver's right). A step with no key pressed is no
correction: the car holds its speed and heading and the learner sees nothing. A step with a key
is one correction, handed to the learner exactly as the simulated humans' are
(``OnlineLearningWrapper``); the robot car (green) then acts by the benchmark's Highway robot
policy for the new θ̂ (``robots.robot_policy``).
The session is logged in the format of every session (``SessionLogger``), so ``replay``,
``export`` and ``fit-human`` read it.

The keys sit behind a ``KeySource`` (``poll() -> (accel, steer)`` in [−1, 1]²) so tests drive
the same loop without a window.

A session ends when its time is up (``duration``), when the cars collide (the panel says so
for ``CRASH_SECONDS`` and the console too), when the window closes, or on Ctrl-C / SIGTERM;
the ``end`` line gives the reason and the simulated time.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from strol_gym.benchmarks.sessions import keys as keymap
from strol_gym.envs.panda.model import has_display
from strol_gym.wrappers import OnlineLearningWrapper
from strol_gym.wrappers.session_log import SessionLogger

NO_WINDOW_HINT = (
    "run it on a virtual display with `xvfb-run -a strol-bench interact --env highway ...` (and "
    'send keys with xdotool), or use the simulated humans, gymnasium.make("StROL-Highway-v0")'
)
NO_DISPLAY_HIGHWAY = (
    "interact --env highway needs a display and a keyboard (DISPLAY is not set): " + NO_WINDOW_HINT
)
POLL_SECONDS = 0.02
"""How often the keys are read within a step (s)."""
KEY_HELP = (
    "KEYS (the blue car is yours): " + keymap.CAR_KEY_HELP[0],
    *keymap.CAR_KEY_HELP[1:],
    "F9: hide this panel. END: close the window (or Ctrl-C in the terminal).",
)
CRASHED = "THE CARS COLLIDED: the session ends"
CRASH_SECONDS = 2.0
"""How long (wall-clock s) the window shows that the cars collided before it closes."""
PANEL_HIDDEN = "F9: show the panel"
HIGHWAY_WORDS = {
    "gap": ("stay close behind the robot car (10 m)", "keep away from the robot car"),
    "speed": ("drive fast", "drive slowly"),
    "lane_change": ("move to the right lane", "stay in the left lane"),
}
"""Per Highway feature: what a positive and a negative weight ask of the human car."""

KeySource = Callable[[], tuple[float, float]]


class KeyboardHuman:
    """The human car's driver as a strol-gym ``Human``: the env asks it for u_H and gets
    what the front end set from the keys this step. It never sees θ̂."""

    needs_theta_hat = False

    def __init__(self, theta_star: np.ndarray) -> None:
        self.theta_star = np.asarray(theta_star, dtype=np.float64)
        self.u = np.zeros(2)

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray | None) -> np.ndarray:
        return self.u.copy()


class PersonCorrections(gym.Wrapper):
    """A step whose u_H is zero (no key) is no correction: the learner and the log skip it."""

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if info.get("is_correction") and not np.any(info["correction"]):
            info = {**info, "is_correction": False}
        return obs, reward, terminated, truncated, info


PYGAME_NAMES = {
    "K_UP": "arrowup",
    "K_DOWN": "arrowdown",
    "K_LEFT": "arrowleft",
    "K_RIGHT": "arrowright",
    "K_w": "w",
    "K_a": "a",
    "K_s": "s",
    "K_d": "d",
}
"""pygame's key constants -> ``keys``' key names (a browser's ``KeyboardEvent.key``)."""


class PygameKeys:
    """The car's keys in highway-env's window, read from pygame's keyboard state (and a
    gamepad's, ``pad``); F9 (pressed, not held) flips ``show_panel``."""

    def __init__(self, pad: Callable[[], keymap.Pad | None] | None = None) -> None:
        self.show_panel = True
        self._f9 = False
        self.pad = pad

    def __call__(self) -> tuple[float, float]:
        import pygame

        pygame.event.pump()
        k = pygame.key.get_pressed()
        if k[pygame.K_F9] and not self._f9:
            self.show_panel = not self.show_panel
        self._f9 = bool(k[pygame.K_F9])
        held = [name for const, name in PYGAME_NAMES.items() if k[getattr(pygame, const)]]
        accel, steer = keymap.car_intent(held)
        state = self.pad() if self.pad is not None else None
        if state is not None:  # per axis, the larger of the keys and the pad
            p_accel, p_steer = keymap.pad_car_intent(state)
            accel, steer = max(accel, p_accel, key=abs), max(steer, p_steer, key=abs)
        return accel, steer


class PersonAtTheKeys:
    """The env's human factory: one ``KeyboardHuman`` per episode (``humans[-1]`` is this
    episode's). Its ``repr`` is what the session log's header records."""

    def __init__(self) -> None:
        self.humans: list[KeyboardHuman] = []

    def __call__(self, task: Any, theta_star: np.ndarray, rng: Any) -> KeyboardHuman:
        self.humans.append(KeyboardHuman(theta_star))
        return self.humans[-1]

    def __repr__(self) -> str:
        return "a person at the keyboard (strol-bench interact --env highway)"


def drive_panel(
    task: Any, info: dict[str, Any], n_corr: int, teach: str, *, blind: bool, cue: str
) -> list[str]:
    """The guidance panel's lines (top left of the window): state, keys, what to teach, and
    θ̂ and φ unless ``blind``."""
    lines = [f"time {info.get('time', 0.0):.1f} s   corrections {n_corr}", *KEY_HELP]
    lines.append("TEACH: " + teach)
    if not blind:
        for name, t, p in zip(task.feature_names, info["theta_hat"], info["phi"], strict=True):
            lines.append(f"{name}: theta_hat {t:+.3f} / phi {p:+.3f}")
    if cue:
        lines.append(cue)
    return lines


HEADLESS_DRIVERS = ("offscreen", "dummy")
"""SDL's video drivers without a window: what it falls back to when DISPLAY names no server."""


def check_window() -> None:
    """ValueError unless pygame opens windows on a screen: with an unreachable DISPLAY, SDL
    falls back to drawing off screen, and the session would run unseen, its log empty."""
    import pygame

    pygame.display.init()
    driver = pygame.display.get_driver()
    if driver in HEADLESS_DRIVERS:
        pygame.display.quit()
        raise ValueError(
            f"interact --env highway cannot open a window on DISPLAY="
            f"{os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY')!r} (SDL fell back "
            f"to its {driver!r} driver: no display server answers there); " + NO_WINDOW_HINT
        )


def run_drive(
    learner: str = "strol",
    learner_kwargs: dict[str, Any] | None = None,
    seed: int = 20000,
    log: str | Path | None = None,
    duration: float = 30.0,
    realtime: bool = True,
    blind: bool = True,
    keys: KeySource | None = None,
    window: bool = True,
    on_step: Callable[[dict[str, Any], list[str]], None] | None = None,
    pad: Callable[[], keymap.Pad | None] | None = None,
    frames: Callable[[np.ndarray], None] | None = None,
    stop: Callable[[], str | None] | None = None,
) -> tuple[Path, dict[str, Any]]:
    """One Highway session driven by a person; returns the log's path and the last ``info``
    (with ``real_time_factor``, ``end_reason`` and ``time``). ``keys`` defaults to the
    window's keys (and ``pad``'s); ``window`` false runs without one (tests);
    ``on_step(info, panel)`` sees each step's panel; ``frames`` (without a window) gets each
    step's picture (highway-env's ``rgb_array``); ``stop()`` returning a reason ends the
    session with it (a page's closed connection)."""
    from strol_gym.benchmarks.engine.robots import robot_policy
    from strol_gym.benchmarks.sessions.person import (
        Pace,
        default_log_path,
        sigterm_stops,
        stop_reason,
    )

    if not (np.isfinite(duration) and 0 < duration <= 86_400):
        raise ValueError(f"duration must be in (0, 86400] seconds, got {duration}")
    if window and not has_display():
        raise ValueError(NO_DISPLAY_HIGHWAY)
    if window:
        check_window()
    path = Path(log) if log is not None else default_log_path()
    if path.exists():
        raise ValueError(f"log {path} exists; sessions are never overwritten")
    person = PersonAtTheKeys()
    from strol_gym.tasks import make_task
    from strol_gym.tasks.highway import HighwayTask

    dt = float(make_task("highway", of=HighwayTask).dt)
    steps = max(1, round(duration / dt))
    base = gym.make(
        "StROL-Highway-v0",
        person=person,
        n_corrections=steps,
        max_episode_steps=steps,
        render_mode="human" if window else ("rgb_array" if frames is not None else None),
        width=900,
        height=300,
    )
    learning = OnlineLearningWrapper(
        PersonCorrections(base), learner, learner_kwargs=learner_kwargs
    )
    hw: Any = learning.unwrapped  # the Highway env (its Task, θ*, highway-env's viewer)
    task = hw.task
    options = {"mode": "interactive-highway", "realtime": realtime, "blind": blind}
    options["duration"] = duration
    env = SessionLogger(learning, path, extra={"interact": options}, auto_end=False)
    policy = robot_policy("task", task)
    bound = np.asarray(task.robot_action_bound, dtype=np.float64)
    a_max = np.asarray(task.action_bound, dtype=np.float64)
    poll = keys
    info: dict[str, Any] = {}
    pace = Pace(dt, realtime)
    n_corr, t, reason = 0, 0.0, ""
    try:
        with sigterm_stops():
            obs, info = env.reset(seed=seed)
            if poll is None:
                poll = PygameKeys(pad)
            teach = _words(task.feature_names, hw.theta_star)
            cue = ""
            if frames is not None:
                frames(hw.render())
            pace = Pace(dt, realtime)
            try:
                while True:
                    # the keys over the step: polled until its end on the wall clock (or once)
                    samples = [poll()]
                    while realtime and time.perf_counter() < pace.t0 + (pace.scheduled + 1) * dt:
                        if window:
                            shown = drive_panel(
                                task, {**info, "time": t}, n_corr, teach, blind=blind, cue=cue
                            )
                            _draw_panel(
                                shown if getattr(poll, "show_panel", True) else [PANEL_HIDDEN]
                            )
                        time.sleep(POLL_SECONDS)
                        samples.append(poll())
                    person.humans[-1].u = keymap.car_correction(samples, a_max)
                    x = np.asarray(obs["state"], dtype=np.float64)[None]
                    u_r = policy(x, np.asarray(learning.learner.theta, dtype=np.float64)[None])[0]
                    action = np.clip(u_r / bound, -1.0, 1.0).astype(np.float32)
                    obs, _, terminated, truncated, info = env.step(action)
                    t += dt
                    if info["is_correction"]:
                        n_corr += 1
                        u = ", ".join(f"{v:+.3f}" for v in info["correction"])
                        cue = f"CORRECTION RECORDED: u_H = ({u}); the robot car replans"
                    else:
                        cue = ""
                    if info.get("crashed"):
                        cue = CRASHED
                    panel = drive_panel(
                        task, {**info, "time": t}, n_corr, teach, blind=blind, cue=cue
                    )
                    if on_step is not None:
                        on_step(info, panel)
                    if frames is not None:
                        frames(hw.render())
                    if window:
                        _draw_panel(panel if getattr(poll, "show_panel", True) else [PANEL_HIDDEN])
                    pace.wait()
                    if info.get("crashed"):
                        reason = "crash: the cars collided"
                        print(f"{CRASHED} (at {t:.1f} s)", flush=True)
                        if window and realtime:
                            time.sleep(CRASH_SECONDS)  # the panel says so before the window goes
                        break
                    if terminated or truncated:
                        reason = "time up"
                        break
                    if window and hw.viewer is None:  # the person closed the window
                        reason = "window closed"
                        break
                    why = stop() if stop is not None else None
                    if why:
                        reason = why
                        break
                env.end_session(reason, {**info, "time": t})
            except KeyboardInterrupt as e:
                reason = stop_reason(e)
                env.end_session(reason, {**info, "time": t}, interrupted=True)
                info = {**info, "interrupted": True}
    finally:
        env.close()
    return path, {
        **info,
        "corrections": n_corr,
        "real_time_factor": pace.factor,
        "end_reason": reason,
        "time": t,
    }


def _words(names: Any, theta_star: np.ndarray) -> str:
    """θ* in words, strongest weight first (weights below 0.1 in size left out)."""
    words = [
        HIGHWAY_WORDS.get(names[i], ("more " + names[i], "less " + names[i]))[
            int(theta_star[i] < 0)
        ]
        for i in np.argsort(-np.abs(theta_star))
        if abs(theta_star[i]) >= 0.1
    ]
    return "drive: " + ", ".join(words) if words else "anything goes (theta* is about 0)"


def _draw_panel(lines: list[str]) -> None:
    """The panel in the window's top-left corner, over highway-env's last frame (the road and
    both cars stay in view below it: the window is 300 px tall, the panel 9 short lines)."""
    import pygame

    surface = pygame.display.get_surface()
    if surface is None:
        return
    font = pygame.font.Font(None, 16)
    y = 2
    for line in lines:
        surface.blit(font.render(line, True, (0, 0, 0), (235, 235, 235)), (4, y))
        y += 13
    pygame.display.flip()


__all__ = [
    "KeyboardHuman",
    "PersonAtTheKeys",
    "PersonCorrections",
    "PygameKeys",
    "drive_panel",
    "run_drive",
]
