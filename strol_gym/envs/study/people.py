"""The people who push the hand, behind one interface: the env reads ``wrench`` once per control
step and does not know whether a simulated user (``user.SimulatedUser``), a simulated
participant (``participant.Participant``), a script (:class:`ScriptedWrench`) or a person at
the viewer (:class:`HeldWrench`, what an interactive front end writes) pushed.

The simulated people's parameters are frozen dataclasses, checked once where they are made
(each error names the person's ``kwargs`` key and its range).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Protocol, runtime_checkable

import numpy as np

from strol_gym import checks
from strol_gym.envs.contract import int_arg

SATISFIED_REGRET = 1.0
"""Default ``satisfied_regret``: the user stops pushing once the regret of the robot's plan (from
home, under its θ*) is at most this (calibrated on seeds 900-919, docs/study.md)."""
TORQUE_LEVER = 0.1
"""A torque τ counts as a force ‖τ‖ / 0.1 m towards the correction threshold."""
CORRECTIONS = ("population", "aimed")
"""The models of a correction a fitted person may use (``FittedParams.correction``)."""
THRESHOLD = 0.4
"""Default acceptance threshold of the participant on the motion's score (calibrated,
docs/study.md)."""


@runtime_checkable
class Pusher(Protocol):
    """Whoever pushes the hand (at the cup), as the env sees them."""

    needs_theta_hat: bool
    """Whether ``wrench`` is handed the robot's θ̂ (a participant sees only the cup: False)."""

    def wrench(
        self, t: float, x: np.ndarray, theta_hat: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(force (3,) N, torque (3,) N m), world frame, at time ``t`` s with the cup at ``x``."""
        ...


class ScriptedWrench:
    """A scripted push: ``force``, ``torque`` for ``steps`` control steps, then nothing."""

    needs_theta_hat = False

    def __init__(self, wrench6: np.ndarray, steps: int) -> None:
        self.wrench6, self.steps = wrench6, steps

    def wrench(
        self, t: float, x: np.ndarray, theta_hat: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """This step's wrench; counts the step."""
        self.steps -= 1
        return self.wrench6[:3], self.wrench6[3:]

    @property
    def done(self) -> bool:
        return self.steps <= 0


class HeldWrench:
    """A wrench held until changed: what a front end writes after reading a person's push (the
    viewer's perturbation after ``sync()``)."""

    needs_theta_hat = False

    def __init__(self) -> None:
        self.wrench6 = np.zeros(6)

    def wrench(
        self, t: float, x: np.ndarray, theta_hat: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        return self.wrench6[:3], self.wrench6[3:]


def _check(name: str, value: float, low: float, strict: bool) -> float:
    return float(checks.number(f"person kwargs[{name!r}]", value, low=low, low_open=strict))


def _check_fields(params: object, lows: dict[str, tuple[float, bool]]) -> None:
    """Check the named fields of a frozen params object in place: each ``name: (low,
    strict)`` a number ≥ low (> low if strict), the error naming its ``person kwargs`` key."""
    for name, (low, strict) in lows.items():
        object.__setattr__(params, name, _check(name, getattr(params, name), low, strict))


@dataclass(frozen=True)
class PushParams:
    """How a simulated person pushes and when it is satisfied (``user.SimulatedUser``)."""

    push_force: float = 40.0
    push_torque: float = 6.0
    ramp: float = 0.2
    max_push: float = 2.0
    decide_every: float = 0.5
    rest: float = 1.5
    min_correction: float = 0.3
    tol: float = 0.015
    ang_tol: float = 0.05
    satisfied_regret: float = SATISFIED_REGRET

    def __post_init__(self) -> None:
        # every field > 0, the regret >= 0
        lows = {f.name: (0.0, f.name != "satisfied_regret") for f in fields(PushParams)}
        _check_fields(self, lows)


@dataclass(frozen=True)
class ParticipantParams(PushParams):
    """The simulated participant's: how it pushes (harder than v0's user) and how it judges the
    cup's motion (``participant.Participant``)."""

    push_force: float = 60.0
    push_torque: float = 8.0
    threshold: float = THRESHOLD
    threshold_noise: float = 0.1
    window: float = 1.0
    min_motion: float = 0.2
    reaction: float = 0.4
    patience: int = 3
    improvement: float = 0.25
    step: float = 0.5
    stall: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        lows = {"threshold_noise": 0.0, "window": 1e-9, "min_motion": 1e-9, "reaction": 0.0}
        lows |= {"improvement": 0.0, "step": 1e-9, "stall": 1e-9}
        _check_fields(self, {name: (low, False) for name, low in lows.items()})
        threshold = float(checks.number("person kwargs['threshold']", self.threshold))
        object.__setattr__(self, "threshold", threshold)
        object.__setattr__(self, "patience", int_arg("person kwargs['patience']", self.patience, 1))


@dataclass(frozen=True)
class FittedParams(ParticipantParams):
    """One person of the fitted population (``population.Population.draw``;
    ``participant.FittedParticipant``): how large and how well aimed its corrections are, how
    many it makes in a session at most, how long it watches after its last one; the pushing
    and judging fields are ``ParticipantParams``' (v2's defaults: ``population.PRIORS``)."""

    size: float = 1.0
    """Median displacement of its corrections (a_max units: 1 = 0.1 m)."""
    size_within: float = 0.7
    """sd of a correction's log displacement about the median."""
    turn: float = 1.0
    """Median rotation of its corrections (Tasks 2-3; a_max units: 1 = 0.3 rad)."""
    turn_within: float = 0.7
    """sd of a correction's log rotation about the median."""
    aim: float = 1.0
    """Its aim's noise τ: the direction is b̂ + τ z (b̂ θ*'s steepest ascent in a_max units,
    z standard normal), then sized."""
    budget: int = 5
    """The most corrections it makes this session (then it is done); unused with ``hazard``."""
    hazard: tuple[float, ...] | None = None
    """(a, b, c[, d]): when it steps in, the fitted timing hazard (``strol_gym.humans.timing``):
    at each judgment it corrects with probability 1 − exp(−rate·``decide_every``), rate =
    exp(a + b·s + (c + d·s)·log(1 + τ)) per s, s the shortfall of the robot's plan, τ the s
    since its last correction. None: it judges the motion's score against ``threshold`` and
    stops after ``budget`` corrections (the learner-independent person)."""
    correction: str = "population"
    """Its model of a correction: ``population`` (its own aim and sizes above, the participant
    fit's) or ``aimed`` (the aimed person fitted per Task, ``strol_gym.humans.aim``)."""
    path_time: float = float("inf")
    """With ``hazard``: the s of the robot's motion it watches (push time not counted), then it
    is done: the logged path time of the real sessions of its Task."""
    doubled_budget: float = float("inf")
    """With ``hazard``: it is done when the s of the robot's motion plus the motion before its
    last correction reach this (the authors' Task 1 loop counted that motion twice,
    ``strol_gym.humans.timing.doubled_end``); inf: only ``path_time`` ends its watch."""
    linger: float = 0.5
    """After its last correction it watches this share of the session so far, then it is done
    (where along the path its corrections fall)."""
    feel: float = 390.0
    """N per m of the intended displacement it pushes with (up to ``push_force``): pushing a
    spring, a person feels how hard to push."""
    feel_rot: float = 13.0
    """N m per rad of the intended turn it twists with (up to ``push_torque``)."""
    min_felt: float = 20.0
    """N: the least push it makes (force + torque / 0.1 m), enough to be felt as one (15 N)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        lows = dict.fromkeys(("size", "turn", "aim", "linger", "feel", "feel_rot"), (0.0, True))
        lows["min_felt"] = (0.0, False)
        lows |= dict.fromkeys(("size_within", "turn_within"), (0.0, False))
        _check_fields(self, lows)
        object.__setattr__(self, "budget", int_arg("person kwargs['budget']", self.budget, 0))
        if self.correction not in CORRECTIONS:
            raise ValueError(
                f"person kwargs['correction'] must be one of {', '.join(CORRECTIONS)}, "
                f"got {self.correction!r}"
            )
        watch = self.path_time
        if isinstance(watch, bool) or not isinstance(watch, int | float) or not watch > 0:
            raise ValueError(f"person kwargs['path_time'] must be a number > 0 (s), got {watch!r}")
        object.__setattr__(self, "path_time", float(watch))
        doubled = self.doubled_budget
        if isinstance(doubled, bool) or not isinstance(doubled, int | float) or not doubled > 0:
            raise ValueError(
                f"person kwargs['doubled_budget'] must be a number > 0 (s), got {doubled!r}"
            )
        object.__setattr__(self, "doubled_budget", float(doubled))
        if self.hazard is not None:
            from strol_gym.humans.timing import hazard_vector

            object.__setattr__(
                self, "hazard", hazard_vector("person kwargs['hazard']", self.hazard)
            )
