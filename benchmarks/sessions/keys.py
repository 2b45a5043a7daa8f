"""What a person's keys and gamepad mean, for every front end of the person sessions.

One mapping, whatever draws the scene: MuJoCo's viewer (GLFW), highway-env's window (pygame)
or a browser page. It knows no window library: a front end translates its own key codes into
**key names**, the lower-case ``KeyboardEvent.key`` values of a browser ("w", "a", "arrowup",
"shift", " " ...), and its gamepad into the W3C Gamepad API's *standard mapping*
(:class:`Pad`), then asks this module what the person means.

The arm (the study env's cup)
    :data:`ARM_KEYS` binds keys to the six axes of an :class:`Intent`: ``right``, ``away``,
    ``up`` (a force) and ``tilt``, ``turn``, ``roll`` (a torque), each in [-1, 1]; Shift
    (:data:`HARDER_KEY`) is "harder". The axes are the camera's as the person sees it:
    ``right`` and ``away`` are horizontal (the camera's right and its forward projected on the
    table), ``up`` is the world's; ``tilt`` tips the cup's top away from the viewer, ``turn``
    turns it to the right seen from above, ``roll`` rolls its top to the right.
    :func:`arm_intent` reads held keys; :func:`pad_arm_intent` a gamepad.
    :class:`ArmPush` turns intents into a wrench: ``push = ArmPush(reflex_force,
    reflex_torque)``, then once per control step ``push.step(intent, dt, azimuth)`` returns a
    :class:`Wrench` (world-frame ``force`` in N and ``torque`` in N m, ``size`` = the force in
    N for the panel, ``torque_size`` in N m, ``harder``). Like a hand, the push's size grows
    and falls at a bounded rate (:attr:`PushSizes.ramp`: seconds from nothing to the plain
    push), a plain push stays below ``below`` of the env's reflex, and only while "harder" is
    held does it grow to ``harder`` times the reflex (the arm brakes: the person learns where
    "too hard" begins). :func:`camera_axes` gives the axes for a MuJoCo camera's azimuth
    (degrees); :func:`azimuth_of` gets the azimuth from any camera's forward vector (a
    browser's camera: ``-R[:, 2]`` of its rotation matrix ``R``).

The car (Highway)
    :data:`CAR_KEYS` binds the arrow keys (and WASD) to ``(accel, steer)`` in [-1, 1]:
    :func:`car_intent` for held keys, :func:`pad_car_intent` for a gamepad. The front end
    samples the intent through the env step (0.5 s) and :func:`car_correction` averages the
    samples into u_H = a_max ⊙ mean(samples): holding Up the whole step is +a_max
    acceleration, half of it +a_max / 2; Right steers towards the right lane; no key, no
    correction (u_H = 0).

A gamepad
    :class:`Pad` holds the standard mapping's ``axes`` (0, 1: left stick x, y; 2, 3: right
    stick x, y; y grows downwards) and ``buttons`` (values in [0, 1]; 0 A, 1 B, 2 X, 3 Y, 4 LB,
    5 RB, 6 LT, 7 RT, 12-15 d-pad up, down, left, right). A browser passes
    ``navigator.getGamepads()[i]``'s arrays as they are; a Python front end (pygame's SDL
    game controller) fills them with :func:`pad_from_sdl`. Sticks have a dead zone
    (:data:`DEAD_ZONE`). The arm: left stick = right / away, RB / LB = up / down, right
    stick = turn / tilt, d-pad left / right = roll, RT held past half = harder. The car: left
    stick x (or d-pad) steers, RT accelerates, LT brakes (or the left stick's y, or the
    d-pad).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from strol_gym.envs.study.people import PushParams

AXES = ("right", "away", "up", "tilt", "turn", "roll")
"""An arm intent's axes: the force's three, then the torque's three (camera frame)."""

ARM_KEYS: Mapping[str, tuple[str, float]] = {
    "d": ("right", 1.0),
    "a": ("right", -1.0),
    "arrowright": ("right", 1.0),
    "arrowleft": ("right", -1.0),
    "w": ("away", 1.0),
    "s": ("away", -1.0),
    "arrowup": ("away", 1.0),
    "arrowdown": ("away", -1.0),
    "e": ("up", 1.0),
    "q": ("up", -1.0),
    "pageup": ("up", 1.0),
    "pagedown": ("up", -1.0),
    "i": ("tilt", 1.0),
    "k": ("tilt", -1.0),
    "l": ("turn", 1.0),
    "j": ("turn", -1.0),
    "o": ("roll", 1.0),
    "u": ("roll", -1.0),
}
"""Key name -> (axis, sign) for the arm. Two keys of one axis pressed together cancel."""
HARDER_KEY = "shift"
"""Held with a push: push harder than the reflex allows (the arm brakes)."""
CUP_KEY = "home"
"""Pressed: the cup is what a mouse drag pushes again (after another link, or nothing, was
selected)."""

ARM_KEY_HELP = (
    "W/S (or Up/Down): push away / towards you; A/D (or Left/Right): left / right;",
    "E/Q (or Page Up/Down): up / down; I/K tilt, J/L turn, U/O roll the cup (Tasks 2-3);",
    "hold Shift to push harder than the reflex allows (the arm brakes); Home: select the cup.",
)
"""The arm's keys in words, for a panel or a help page."""

CAR_KEYS: Mapping[str, tuple[int, float]] = {
    "arrowup": (0, 1.0),
    "arrowdown": (0, -1.0),
    "arrowright": (1, 1.0),
    "arrowleft": (1, -1.0),
    "w": (0, 1.0),
    "s": (0, -1.0),
    "d": (1, 1.0),
    "a": (1, -1.0),
}
"""Key name -> (index in (accel, steer), sign) for the car."""

CAR_KEY_HELP = (
    "Up / Down (or W / S): accelerate / brake; Left / Right (or A / D): steer.",
    "Holding a key for the whole 0.5 s step = the full a_max; no key = no correction.",
)

DEAD_ZONE = 0.15
"""A stick's deflection below this counts as none (sticks rarely rest at exactly 0)."""
PAD_HARDER = 0.5
"""RT pressed past this (of its travel) is "harder"."""


def key_name(name: str) -> str:
    """A key's name as this module spells it: lower case ("ArrowUp" -> "arrowup"; "W" with
    Shift held -> "w")."""
    return name.lower()


class Intent(NamedTuple):
    """What the person asks of the arm: each axis in [-1, 1] (see :data:`AXES`)."""

    right: float = 0.0
    away: float = 0.0
    up: float = 0.0
    tilt: float = 0.0
    turn: float = 0.0
    roll: float = 0.0
    harder: bool = False

    @property
    def force(self) -> np.ndarray:
        return np.array([self.right, self.away, self.up])

    @property
    def torque(self) -> np.ndarray:
        return np.array([self.tilt, self.turn, self.roll])


def _clip(v: float) -> float:
    return max(-1.0, min(1.0, float(v)))


def arm_intent(held: Iterable[str]) -> Intent:
    """The arm intent of the keys held now (names as :func:`key_name` spells them; unknown
    names are ignored). Keys of one axis add up and are clipped to [-1, 1]."""
    names = {key_name(k) for k in held}
    axes = dict.fromkeys(AXES, 0.0)
    # one count per (axis, sign): "d" and "arrowright" together are still +1
    for axis, sign in {ARM_KEYS[k] for k in names if k in ARM_KEYS}:
        axes[axis] += sign
    return Intent(**{a: _clip(v) for a, v in axes.items()}, harder=HARDER_KEY in names)


def car_intent(held: Iterable[str]) -> tuple[float, float]:
    """``(accel, steer)`` in [-1, 1] of the keys held now (Up - Down, Right - Left)."""
    names = {key_name(k) for k in held}
    out = [0.0, 0.0]
    for index, sign in {CAR_KEYS[k] for k in names if k in CAR_KEYS}:
        out[index] += sign
    return _clip(out[0]), _clip(out[1])


def car_correction(
    samples: Sequence[Sequence[float]], a_max: Sequence[float] | np.ndarray
) -> np.ndarray:
    """u_H of one Highway step: ``a_max`` ⊙ the mean of the ``(accel, steer)`` intents
    sampled through it (clipped to [-1, 1]); no samples, no correction."""
    if len(samples) == 0:
        return np.zeros(len(a_max))
    mean = np.clip(np.mean(np.asarray(samples, dtype=np.float64), axis=0), -1.0, 1.0)
    return np.asarray(a_max, dtype=np.float64) * mean


# ---------------------------------------------------------------------- the camera's frame
def camera_axes(azimuth: float) -> np.ndarray:
    """The push's axes in the world for a camera at ``azimuth`` degrees (MuJoCo's free
    camera: it looks along (cos az, sin az) on the table): columns right, away (both
    horizontal), up (the world's z). A right-handed frame."""
    az = math.radians(azimuth)
    away = np.array([math.cos(az), math.sin(az), 0.0])
    right = np.array([math.sin(az), -math.cos(az), 0.0])
    return np.column_stack([right, away, [0.0, 0.0, 1.0]])


def azimuth_of(forward: Sequence[float]) -> float:
    """The azimuth (degrees, MuJoCo's convention) of a camera looking along ``forward``
    (world, z up). Looking straight down or up has no azimuth: ValueError."""
    f = np.asarray(forward, dtype=np.float64)
    if f.shape != (3,) or not np.isfinite(f).all():
        raise ValueError(f"forward must be 3 finite numbers, got {forward!r}")
    if math.hypot(f[0], f[1]) < 1e-9:
        raise ValueError("forward points straight up or down: the camera has no azimuth")
    return math.degrees(math.atan2(f[1], f[0]))


def to_world(intent: Intent, azimuth: float) -> tuple[np.ndarray, np.ndarray]:
    """The intent's force and torque directions in the world (not normalised). ``tilt`` tips
    the top away (a torque about -right), ``turn`` turns it right seen from above (about
    -up), ``roll`` rolls the top right (about +away)."""
    frame = camera_axes(azimuth)
    torque = np.array([-intent.tilt, intent.roll, -intent.turn])  # about right, away, up
    return frame @ intent.force, frame @ torque


# ---------------------------------------------------------------------- a hand's push
@dataclass(frozen=True)
class PushSizes:
    """How hard the keys push. Defaults: the simulated users' push (``PushParams``'s
    ``push_force``, ``push_torque`` and ``ramp``, read from there)."""

    force: float = PushParams.push_force
    """N: a plain push's force."""
    torque: float = PushParams.push_torque
    """N m: a plain push's torque."""
    ramp: float = PushParams.ramp
    """s from nothing to a plain push (and back): the size changes at force / ramp per s."""
    below: float = 0.8
    """A plain push stays at or below this share of the env's reflex (force and torque)."""
    harder: float = 1.25
    """With "harder" held the push grows to this multiple of the reflex (or of the plain
    push's size where the env has no reflex)."""

    def __post_init__(self) -> None:
        for name in ("force", "torque", "ramp", "below", "harder"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < math.inf:
                raise ValueError(f"PushSizes.{name} must be a finite number > 0, got {v!r}")
        if self.below >= 1.0:
            raise ValueError(f"PushSizes.below must be < 1 (below the reflex), got {self.below}")
        if self.harder <= 1.0:
            raise ValueError(f"PushSizes.harder must be > 1 (past the reflex), got {self.harder}")


class Wrench(NamedTuple):
    """One control step's push: world-frame ``force`` (N) and ``torque`` (N m), their sizes
    (``size`` N, ``torque_size`` N m: what the panel shows) and whether "harder" was held."""

    force: np.ndarray
    torque: np.ndarray
    size: float
    torque_size: float
    harder: bool


@dataclass
class ArmPush:
    """Intents -> a hand's push on the cup, advanced once per control step (module
    docstring). ``reflex_force`` (N) and ``reflex_torque`` (N m): the env's reflex (inf: none)."""

    reflex_force: float = math.inf
    reflex_torque: float = math.inf
    sizes: PushSizes = field(default_factory=PushSizes)
    size: float = 0.0
    """N now (the force's magnitude)."""
    torque_size: float = 0.0
    """N m now."""
    _force_dir: np.ndarray = field(default_factory=lambda: np.zeros(3))
    _torque_dir: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        for name in ("reflex_force", "reflex_torque"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not v > 0:
                raise ValueError(f"{name} must be a number > 0 (inf: no reflex), got {v!r}")

    def limits(self, harder: bool) -> tuple[float, float]:
        """The force (N) and torque (N m) a push grows to, plain or harder."""
        s = self.sizes
        out = []
        for plain, reflex in ((s.force, self.reflex_force), (s.torque, self.reflex_torque)):
            if math.isinf(reflex):
                out.append(plain * (s.harder if harder else 1.0))
            else:
                out.append(s.harder * reflex if harder else min(plain, s.below * reflex))
        return out[0], out[1]

    def ceiling(self, harder: bool) -> tuple[float, float]:
        """The most force (N) and torque (N m) any push of the person's gets (a mouse drag's
        cap): ``below`` of the reflex, or ``harder`` times it while "harder" is held (inf
        where the env has no reflex)."""
        share = self.sizes.harder if harder else self.sizes.below
        return share * self.reflex_force, share * self.reflex_torque

    def step(self, intent: Intent, dt: float, azimuth: float) -> Wrench:
        """Advance ``dt`` seconds under ``intent`` with the camera at ``azimuth`` degrees."""
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"dt must be a finite number >= 0 s, got {dt!r}")
        force_dir, torque_dir = to_world(intent, azimuth)
        force_max, torque_max = self.limits(intent.harder)
        rate_f = self.sizes.force / self.sizes.ramp * dt
        rate_t = self.sizes.torque / self.sizes.ramp * dt
        self.size, self._force_dir = _ramp(self.size, force_dir, self._force_dir, force_max, rate_f)
        self.torque_size, self._torque_dir = _ramp(
            self.torque_size, torque_dir, self._torque_dir, torque_max, rate_t
        )
        return Wrench(
            self.size * self._force_dir,
            self.torque_size * self._torque_dir,
            self.size,
            self.torque_size,
            intent.harder,
        )

    def release(self) -> None:
        """Let go at once (the window lost the keys, the session ends)."""
        self.size = self.torque_size = 0.0
        self._force_dir = np.zeros(3)
        self._torque_dir = np.zeros(3)


def _ramp(
    size: float, want: np.ndarray, last: np.ndarray, top: float, rate: float
) -> tuple[float, np.ndarray]:
    """One axis group's size and unit direction after a step: towards ``top`` along ``want``
    when it is not zero, towards nothing along ``last`` when it is (a hand letting go)."""
    n = float(np.linalg.norm(want))
    if n > 1e-12:
        direction, target = want / n, top * min(1.0, n)
    else:
        direction, target = last, 0.0
    size = min(target, size + rate) if size < target else max(target, size - rate)
    return size, (direction if size > 0 else np.zeros(3))


# ---------------------------------------------------------------------- a gamepad
@dataclass(frozen=True)
class Pad:
    """A gamepad's state in the W3C standard mapping (module docstring): ``axes`` in [-1, 1]
    (at least 4), ``buttons`` in [0, 1] (missing ones read 0)."""

    axes: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    buttons: tuple[float, ...] = ()

    @classmethod
    def of(cls, axes: Sequence[float], buttons: Sequence[float | bool]) -> Pad:
        """From a browser's ``gamepad.axes`` and ``[b.value for b in gamepad.buttons]``
        (anything not a finite number reads 0)."""

        def num(v: float | bool) -> float:
            x = float(v)
            return x if math.isfinite(x) else 0.0

        return cls(tuple(num(a) for a in axes), tuple(num(b) for b in buttons))

    def axis(self, i: int) -> float:
        """Axis ``i`` with the dead zone applied (0 within it, rescaled to reach ±1 beyond)."""
        v = _clip(self.axes[i]) if i < len(self.axes) else 0.0
        if abs(v) <= DEAD_ZONE:
            return 0.0
        return math.copysign((abs(v) - DEAD_ZONE) / (1.0 - DEAD_ZONE), v)

    def button(self, i: int) -> float:
        return max(0.0, min(1.0, self.buttons[i])) if i < len(self.buttons) else 0.0


A, B, X, Y, LB, RB, LT, RT = range(8)
DPAD_UP, DPAD_DOWN, DPAD_LEFT, DPAD_RIGHT = 12, 13, 14, 15


def pad_arm_intent(pad: Pad) -> Intent:
    """The arm intent of a gamepad (module docstring)."""
    b = pad.button
    return Intent(
        right=pad.axis(0),
        away=-pad.axis(1),
        up=_clip(b(RB) - b(LB)),
        tilt=-pad.axis(3),
        turn=pad.axis(2),
        roll=_clip(b(DPAD_RIGHT) - b(DPAD_LEFT)),
        harder=b(RT) > PAD_HARDER,
    )


def pad_car_intent(pad: Pad) -> tuple[float, float]:
    """``(accel, steer)`` of a gamepad: RT - LT, or the left stick's y, or the d-pad (the
    largest in size wins); steer from the left stick's x or the d-pad."""
    b = pad.button
    accel = max((b(RT) - b(LT), -pad.axis(1), b(DPAD_UP) - b(DPAD_DOWN)), key=abs)
    steer = max((pad.axis(0), b(DPAD_RIGHT) - b(DPAD_LEFT)), key=abs)
    return _clip(accel), _clip(steer)


SDL_AXES = ("leftx", "lefty", "rightx", "righty")
"""SDL game controller axes in standard-mapping order (their values: int16, ±32767)."""
SDL_TRIGGERS = {LT: "triggerleft", RT: "triggerright"}
"""Standard buttons that SDL reports as axes (0..32767)."""
SDL_BUTTONS = {
    A: "a",
    B: "b",
    X: "x",
    Y: "y",
    LB: "leftshoulder",
    RB: "rightshoulder",
    8: "back",
    9: "start",
    10: "leftstick",
    11: "rightstick",
    DPAD_UP: "dpad_up",
    DPAD_DOWN: "dpad_down",
    DPAD_LEFT: "dpad_left",
    DPAD_RIGHT: "dpad_right",
    16: "guide",
}
"""Standard button index -> SDL game controller button name."""


def pad_from_sdl(axes: Mapping[str, float], buttons: Mapping[str, bool | float]) -> Pad:
    """A :class:`Pad` from an SDL game controller's raw readings by SDL name (e.g. pygame's
    ``pygame._sdl2.controller``: ``get_axis(CONTROLLER_AXIS_LEFTX)`` under "leftx",
    ``get_button(CONTROLLER_BUTTON_A)`` under "a"); missing names read 0."""
    scale = 32767.0
    ax = tuple(float(axes.get(n, 0)) / scale for n in SDL_AXES)
    btn = [float(buttons.get(SDL_BUTTONS[i], 0)) if i in SDL_BUTTONS else 0.0 for i in range(17)]
    for i, name in SDL_TRIGGERS.items():
        btn[i] = max(0.0, float(axes.get(name, 0)) / scale)
    return Pad.of(ax, btn)


__all__ = [
    "ARM_KEYS",
    "ARM_KEY_HELP",
    "AXES",
    "CAR_KEYS",
    "CAR_KEY_HELP",
    "CUP_KEY",
    "DEAD_ZONE",
    "HARDER_KEY",
    "ArmPush",
    "Intent",
    "Pad",
    "PushSizes",
    "Wrench",
    "arm_intent",
    "azimuth_of",
    "camera_axes",
    "car_correction",
    "car_intent",
    "key_name",
    "pad_arm_intent",
    "pad_car_intent",
    "pad_from_sdl",
    "to_world",
]
