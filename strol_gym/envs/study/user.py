"""A simulated study participant: decides when and where to correct, and pushes the arm there.

What it wants comes from the suite's human models (``strol_gym.humans``: "nominal" is eq. M6,
"boltzmann" is Boltzmann-rational with β; σ and ε are fractions of the largest admissible
correction a_max): every ``decide_every`` seconds it first judges the robot's current behaviour:
the regret under its θ* of the robot's plan for θ̂ from home (``task.regret(θ̂, θ*, start)``,
the study's own metric; computed once per distinct θ̂, which changes only after corrections). If
that regret is at most ``satisfied_regret`` it is satisfied and does not push. Otherwise it asks
its model for a correction u from the cup's current pose. If |u| is at least ``min_correction``
of a_max on some axis, the pose x + u becomes its target and it pushes: the force (and, for 6-D
Tasks, the torque) points from the cup's pose to the target, ramps up over ``ramp`` seconds,
holds, tapers when within a few centimetres, and is released (ramped down) when the target is
reached (``tol``, ``ang_tol``) or after ``max_push`` seconds (tired). It then rests ``rest``
seconds before deciding again.

Its only randomness is its model's, drawn from the generator it is given: a pure function of its
seed. The env reads it through ``wrench`` once per control step, exactly as it reads a scripted
wrench or a person's push through the viewer (one interface, see docs/study.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from strol_gym.envs.study.geometry import (  # noqa: F401  (angle_delta: here until 0.2)
    angle_delta,
    rotation_error,
)
from strol_gym.envs.study.people import SATISFIED_REGRET, PushParams  # noqa: F401
from strol_gym.humans import HumanFactory, make_human
from strol_gym.tasks.study import StudyTask, rpy_to_mat


class SimulatedUser:
    """A seeded study participant (see the module docstring). ``theta_star`` is its preference."""

    needs_theta_hat: bool = True
    """It judges the robot's plan for θ̂ (``people.Pusher``): the env hands it θ̂."""
    taper: float = 0.03
    """m from its target where the push's force starts to fall (linearly, to 0 at the target)."""
    ang_taper: float = 0.1
    """rad from its target orientation where the torque starts to fall."""

    def __init__(
        self,
        task: StudyTask,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        *,
        model: str | HumanFactory = "nominal",
        sigma: float = 0.0,
        bias: float = 0.0,
        beta: float = 50.0,
        human_kwargs: dict[str, Any] | None = None,
        params: PushParams | None = None,
        **push: Any,
    ) -> None:
        """``params``, or its fields as keywords (the person's ``kwargs``), say how it pushes."""
        self.params = params if params is not None else PushParams(**push)
        self._regrets: dict[bytes, float] = {}
        self.task = task
        self.model = make_human(
            model, task, theta_star, rng, sigma=sigma, bias=bias, beta=beta, **(human_kwargs or {})
        )
        self.phase = "idle"
        self.target: np.ndarray | None = None
        self._t_next = 0.0
        self._t0 = 0.0
        self._level = 0.0

    @property
    def theta_star(self) -> np.ndarray:
        return np.asarray(self.model.theta_star, dtype=np.float64)

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
        """The correction its model wants (the ``Human`` interface)."""
        return self.model.act(x, u_r, theta_hat)

    def regret(self, theta_hat: np.ndarray) -> float:
        """The regret under θ* of the robot's plan for ``theta_hat`` from home (cached)."""
        theta_hat = np.asarray(theta_hat, dtype=np.float64)
        key = theta_hat.tobytes()
        if key not in self._regrets:
            r = self.task.regret(theta_hat, self.theta_star, self.task.start)
            self._regrets[key] = float(np.asarray(r).reshape(-1)[0])
        return self._regrets[key]

    def satisfied(self, theta_hat: np.ndarray) -> bool:
        """Whether the robot's current plan is good enough: regret <= ``satisfied_regret``."""
        return self.regret(theta_hat) <= self.params.satisfied_regret

    def _released(self, t: float, x: np.ndarray) -> None:
        """Called when a push has been let go (a hook for participants that keep count)."""

    def _decide(self, t: float, x: np.ndarray, theta_hat: np.ndarray | None) -> np.ndarray | None:
        """While idle: the pose to push the cup to now, or None (judged every
        ``decide_every`` s: unsatisfied by the plan's regret, and a large enough correction)."""
        if t + 1e-9 < self._t_next:
            return None
        if theta_hat is None:  # needs_theta_hat: the env hands it θ̂
            raise ValueError("a SimulatedUser judges the robot's plan: pass theta_hat")
        self._t_next = t + self.params.decide_every
        if self.satisfied(theta_hat):
            return None
        u = np.asarray(self.act(x, np.zeros(self.task.action_dim), theta_hat))
        if np.max(np.abs(u) / self.task.action_bound) < self.params.min_correction:
            return None
        return self.task.dynamics(x, u, np.zeros_like(u))

    def _error(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(position error (3,), rotation error (3,)) from the cup's pose to the target."""
        assert self.target is not None
        dp = self.target[:3] - x[:3]
        if not self.task.oriented:
            return dp, np.zeros(3)
        return dp, rotation_error(rpy_to_mat(self.target[3:]), rpy_to_mat(x[3:]))

    def wrench(
        self, t: float, x: np.ndarray, theta_hat: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(force N, torque N m) on the hand at time ``t`` (s), the cup at pose ``x``."""
        zero = np.zeros(3)
        if self.phase == "idle":
            target = self._decide(t, x, theta_hat)
            if target is None:
                return zero, zero
            self.target = target
            self.phase, self._t0 = "push", t
        if self.target is None:
            return zero, zero
        dp, dr = self._error(x)
        if self.phase == "push":
            done = np.linalg.norm(dp) < self.params.tol and np.linalg.norm(dr) < self.params.ang_tol
            if done or t - self._t0 >= self.params.max_push:
                self.phase, self._t0 = "release", t
            else:
                self._level = min(1.0, (t - self._t0 + 1e-9) / self.params.ramp)
        level = self._level
        if self.phase == "release":
            level = self._level * max(0.0, 1.0 - (t - self._t0) / self.params.ramp)
            if level <= 0.0:
                self.phase, self._t_next, self.target = "idle", t + self.params.rest, None
                self._released(t, x)
                return zero, zero
        n_p, n_r = np.linalg.norm(dp), np.linalg.norm(dr)
        force = dp / max(n_p, 1e-9) * self.params.push_force * min(1.0, n_p / self.taper)
        torque = dr / max(n_r, 1e-9) * self.params.push_torque * min(1.0, n_r / self.ang_taper)
        if not self.task.oriented:
            torque = zero
        return level * force, level * torque
