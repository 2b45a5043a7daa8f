"""The people who push the hand, behind one interface: the env reads ``wrench`` once per control
step and does not know whether a simulated user (``user.SimulatedUser``), a simulated
participant (``participant.Participant``), a script (:class:`ScriptedWrench`) or a person at
the viewer (:class:`HeldWrench`, what an interactive front end writes) pushed.

The simulated people's parameters are frozen dataclasses, checked once where they are made
(each error names the ``user_kwargs`` key and its range).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Protocol, runtime_checkable

import numpy as np

SATISFIED_REGRET = 1.0
"""Default ``satisfied_regret``: the user stops pushing once the regret of the robot's plan (from
home, under its θ*) is at most this (calibrated on seeds 900-919, docs/study.md)."""
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
    v = float(value)
    if not (math.isfinite(v) and (v > low if strict else v >= low)):
        rng = f"> {low:g}" if strict else f">= {low}"
        raise ValueError(f"user_kwargs[{name!r}] must be a finite number {rng}, got {v}")
    return v


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
        for f in fields(PushParams):
            strict = f.name != "satisfied_regret"  # the others > 0, the regret >= 0
            low = 0.0 if strict else 0
            object.__setattr__(self, f.name, _check(f.name, getattr(self, f.name), low, strict))


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
        for name, low in (
            ("threshold_noise", 0.0),
            ("window", 1e-9),
            ("min_motion", 1e-9),
            ("reaction", 0.0),
            ("improvement", 0.0),
            ("step", 1e-9),
            ("stall", 1e-9),
        ):
            object.__setattr__(self, name, _check(name, getattr(self, name), low, strict=False))
        threshold = float(self.threshold)
        if not math.isfinite(threshold):
            raise ValueError(f"user_kwargs['threshold'] must be finite, got {self.threshold!r}")
        object.__setattr__(self, "threshold", threshold)
        p = self.patience
        if isinstance(p, bool) or not isinstance(p, int | np.integer) or p < 1:
            raise ValueError(f"user_kwargs['patience'] must be an integer >= 1, got {p!r}")
        object.__setattr__(self, "patience", int(p))
