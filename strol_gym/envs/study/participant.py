"""A study participant who judges from what they see (StROL-Study-v1's default simulated person).

v0's ``SimulatedUser`` decides whether to push from the planner's exact regret of θ̂'s plan: an
oracle no person has. ``Participant`` sees only the cup: every control step the env hands it
the time and the cup's pose (``wrench(t, x)``; it is given no θ̂, and it never calls the Task's
planner or regret). It pushes the arm with the same mechanics as ``SimulatedUser`` (ramp, hold,
taper, release, rest), but decides differently:

- **Judging the motion.** Every ``decide_every`` s it looks at the cup's motion over the last
  ``window`` s: if the cup moved (≥ ``min_motion`` of a correction's a_max, in a_max units), the
  motion's score is its gain under the participant's θ*, θ*·(φ(x_now) − φ(x_then)), divided by
  the best gain of a move of the same size from x_then (over the candidate directions below).
  1 = the best it could imagine, 0 = useless, < 0 = the wrong way. It accepts the motion if
  the score is at least its threshold: ``threshold`` plus N(0, ``threshold_noise``²) drawn
  per judgment. A cup at rest is not judged, nor one heading back to where the trial began
  (the robot returns home and plays its plan again, as participants are told).
- **Reaction time.** It starts pushing ``reaction`` s after it rejected the motion, from the
  pose it sees then.
- **Where it pushes (θ*-greedy).** Over candidate displacements of the pose it sees, each axis
  in {−1, 0, 1} × ``step`` × a_max (``step`` 0.5: position; and roll, pitch for Tasks 2-3: yaw
  does not matter to it; it pushes with up to 60 N and 8 N m, below the reflex, so the target
  is within reach),
  it takes the one with the best θ*·φ(x + d), then adds its hand's noise: N(0, σ²) and the bias
  ε per axis, as fractions of a_max (the env's ``sigma`` and ``bias``, the training human's).
- **Feeling the arm.** It pushes nearly full force until the cup is within 1 cm and 0.03 rad
  of its target (``taper``, ``ang_taper``), and lets go early when the cup stops giving: over
  the last ``stall`` s (0.5) the push brought it < 0.02 a_max closer (the arm's reach, a joint
  limit, the table).
- **Patience.** After each push it compares the next motion it judges with the one it
  pushed against; if ``patience`` pushes in a row bring no better score (by ``improvement``),
  it gives up and pushes no more this episode (``gave_up``), as some of the paper's
  participants did.

Its randomness (threshold noise, hand noise) is drawn from the generator it is given.
Calibration of ``threshold`` on seeds outside the study's: ``docs/study.md``.
"""

from __future__ import annotations

import collections
import dataclasses
import itertools
import math
from typing import Any

import numpy as np

from strol_gym.envs.study.geometry import angle_delta
from strol_gym.envs.study.people import (  # noqa: F401  (THRESHOLD: here until 0.2)
    THRESHOLD,
    TORQUE_LEVER,
    FittedParams,
    ParticipantParams,
)
from strol_gym.envs.study.population import aimed_correction, best_correction, draw_corrections
from strol_gym.envs.study.user import SimulatedUser
from strol_gym.humans import check_fraction
from strol_gym.humans.timing import hazard_rate, shortfall, step_in_probability
from strol_gym.tasks.study import StudyTask


class Participant(SimulatedUser):
    """A simulated participant who sees the cup, not the robot's θ̂ (the module docstring)."""

    needs_theta_hat = False
    """The env hands it no θ̂ (``wrench`` is called with ``theta_hat=None``)."""
    taper = 0.01
    ang_taper = 0.03
    """It keeps pushing nearly full until the cup is close (1 cm, 0.03 rad): v0's user's taper
    (3 cm, 0.1 rad) against v1's 400 N/m and 30 N m/rad held the cup short of its tolerance
    (1.5 cm, 0.05 rad), so most 6-D pushes ran to the 2 s limit (docs/study.md)."""

    def __init__(
        self,
        task: StudyTask,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        *,
        sigma: float = 0.0,
        bias: float = 0.0,
        params: ParticipantParams | None = None,
        **kwargs: Any,
    ) -> None:
        """``params``, or its fields as keywords (the person's ``kwargs``), say how it pushes and
        judges (not both). A keyword that is not a field is refused by name: v0's user's
        ``model``, ``beta`` and ``human_kwargs`` mean nothing here (it judges what it sees)."""
        fields = sorted(f.name for f in dataclasses.fields(ParticipantParams))
        unknown = sorted(set(kwargs) - set(fields))
        if unknown:
            raise ValueError(
                f"Participant does not take {unknown}: it takes sigma, bias, params or the fields "
                f"of ParticipantParams ({', '.join(fields)})"
            )
        if params is not None and kwargs:
            raise ValueError(f"Participant takes params or its fields {sorted(kwargs)}, not both")
        params = params if params is not None else ParticipantParams(**kwargs)
        super().__init__(task, theta_star, rng, params=params)
        self.params: ParticipantParams = params
        self.task = task
        self._theta_star = np.asarray(theta_star, dtype=np.float64).copy()
        self.rng = rng
        self.sigma = check_fraction("sigma", sigma)
        self.bias = check_fraction("bias", bias, allow_negative=True)
        a_max = task.action_bound
        axes = task.action_dim if not task.oriented else 5  # yaw is not a candidate axis
        grid = np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=axes)))
        grid = grid[np.any(grid != 0.0, axis=1)]
        full = np.zeros((len(grid), task.action_dim))
        full[:, :axes] = grid
        self._candidates = full * a_max * self.params.step
        self._unit = full / np.linalg.norm(full, axis=1, keepdims=True)  # in a_max units
        self._a_max = a_max
        self._seen: collections.deque[tuple[float, np.ndarray]] = collections.deque()
        self._home: np.ndarray | None = None
        self._push_at: float | None = None
        self._rejected = -math.inf
        self._since_better = 0
        self._pending_score: float | None = None
        self._gaps: collections.deque[tuple[float, float]] = collections.deque()
        self.gave_up = False
        self.judgments = 0
        self.rejections = 0

    @property
    def theta_star(self) -> np.ndarray:
        return self._theta_star.copy()

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: Any = None) -> np.ndarray:
        """The θ*-greedy displacement of pose ``x`` plus the hand's noise and bias."""
        del u_r, theta_hat
        x = np.asarray(x, dtype=np.float64)
        value = self.task.features(x[None, :] + self._candidates) @ self._theta_star
        d = self._candidates[int(np.argmax(value))].copy()
        noise = self.rng.normal(0.0, self.sigma, size=d.shape) if self.sigma else 0.0
        return d + (noise + self.bias) * self._a_max

    def _target(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The pose it pushes the cup towards: the Task's step x + u (clipped to its planning
        box, angles wrapped)."""
        return self.task.dynamics(x, u, np.zeros_like(u))

    def score(self, x_then: np.ndarray, x_now: np.ndarray) -> float | None:
        """The observed motion's θ*-gain over the best gain of a move of the same size (None if
        the cup barely moved)."""
        step = angle_delta(x_now, x_then)[: self.task.action_dim]
        if self.task.oriented:
            step[5] = 0.0  # yaw: not seen as part of the motion's worth
        size = float(np.linalg.norm(step / self._a_max))
        if size < self.params.min_motion:
            return None
        phi0 = self.task.features(x_then)
        gain = float((self.task.features(x_now) - phi0) @ self._theta_star)
        moves = x_then[None, :] + self._unit * (size * self._a_max)
        best = float(np.max((self.task.features(moves) - phi0) @ self._theta_star))
        if best <= 1e-12:
            return 1.0 if gain >= -1e-12 else -1.0
        return gain / best

    def satisfied(self, theta_hat: Any = None) -> bool:  # v0's oracle test: not available
        raise AttributeError("a Participant judges the motion it sees, not the robot's plan")

    def regret(self, theta_hat: Any = None) -> float:
        raise AttributeError("a Participant does not know the planner's regret")

    def wrench(
        self, t: float, x: np.ndarray, theta_hat: Any = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(force N, torque N m) at time ``t`` with the cup at pose ``x`` (θ̂ is used only by a
        person who ``needs_theta_hat``)."""
        if self._home is None:
            self._home = np.array(x, dtype=np.float64)  # where the robot starts each trial
        self._seen.append((t, np.array(x, dtype=np.float64)))
        while len(self._seen) > 1 and self._seen[1][0] <= t - self.params.window + 1e-9:
            self._seen.popleft()
        if self.phase == "push" and self._stalled(t, x):
            self.phase, self._t0 = "release", t  # the cup no longer gives: let go
        return super().wrench(t, x, theta_hat if self.needs_theta_hat else None)

    def _stalled(self, t: float, x: np.ndarray) -> bool:
        """Whether the push has stopped bringing the cup closer: over the last ``stall`` s its
        distance to the target (position and angles in a_max units) fell by < 0.02 (2 mm or
        0.006 rad). A person feels the arm stop giving (its reach, a joint limit, the table)
        and lets go, rather than pushing on until tired."""
        if self._gaps and self._gaps[0][0] < self._t0 - 1e-9:
            self._gaps.clear()  # a new push
        dp, dr = self._error(x)
        a = self._a_max
        gap = math.hypot(float(np.linalg.norm(dp)) / a[0], float(np.linalg.norm(dr)) / a[-1])
        self._gaps.append((t, gap))
        while len(self._gaps) > 1 and self._gaps[1][0] <= t - self.params.stall + 1e-9:
            self._gaps.popleft()
        t0, g0 = self._gaps[0]
        return t - t0 >= self.params.stall - 1e-9 and g0 - gap < 0.02

    def _decide(self, t: float, x: np.ndarray, theta_hat: Any) -> np.ndarray | None:
        del theta_hat
        if self.gave_up:
            return None
        if self._push_at is not None:  # reacting: push from what it sees now
            if t + 1e-9 < self._push_at:
                return None
            self._push_at = None
            u = self.act(x, np.zeros(self.task.action_dim))
            return self._target(x, u)
        if t + 1e-9 < self._t_next:
            return None
        self._t_next = t + self.params.decide_every
        t0, x0 = self._seen[0]
        if t - t0 < self.params.window - 1e-9:
            return None
        if self._returning(x0, x):
            return None
        s = self.score(x0, x)
        if s is None:
            return None
        self.judgments += 1
        if self._pending_score is not None:  # the first judgment since its last push
            if s > self._pending_score + self.params.improvement:
                self._since_better = 0
            else:
                self._since_better += 1
                if self._since_better >= self.params.patience:
                    self.gave_up = True
                    return None
            self._pending_score = None
        accept = s >= self.params.threshold + self.params.threshold_noise * self.rng.normal()
        if accept:
            return None
        self.rejections += 1
        self._rejected = s
        self._push_at = t + self.params.reaction
        if self.params.reaction <= 0.0:
            return self._decide(t, x, None)
        return None

    def _returning(self, x_then: np.ndarray, x_now: np.ndarray) -> bool:
        """Whether the cup is heading back to where the trial started (the robot resets
        between trials, as the participant was told): not the behaviour it is judging."""
        assert self._home is not None
        step, back = x_now[:3] - x_then[:3], self._home[:3] - x_then[:3]
        n_s, n_b = float(np.linalg.norm(step)), float(np.linalg.norm(back))
        return n_s > 0.0 and n_b > 0.0 and float(step @ back) > 0.9 * n_s * n_b

    def _released(self, t: float, x: np.ndarray) -> None:
        self._pending_score = self._rejected  # what the push was meant to improve
        self._seen.clear()  # judge the robot's motion after the push, not the push itself


class FittedParticipant(Participant):
    """A person of the fitted population (StROL-Study-v2's default, ``participant="fitted"``;
    ``population``): it judges the cup's motion as ``Participant`` does, and:

    - **where it pushes** is drawn from the fit: the direction θ*'s steepest ascent at the
      pose it sees (in a_max units) plus its aim's noise, the displacement and rotation its
      own log-normal sizes (``population.draw_corrections``); the env's ``sigma`` and
      ``bias`` are not used (its noise is fitted);
    - **when it is done**: after ``budget`` corrections it pushes no more this session; it
      watches ``linger`` × the path time it had watched before its last push, then it is
      done: ``done_at`` (s; None until then);
    - **it lets go along its push**: while the force falls (``ramp``) it keeps the push's
      direction rather than re-aiming at the target, so a cup that overshoots is not pushed
      back (v1's participant's rebounds: a second, opposite correction < 0.5 s later);
    - it watches ``rest`` s before its first judgment, as after each push.
    """

    def __init__(
        self,
        task: StudyTask,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        *,
        sigma: float = 0.0,
        bias: float = 0.0,
        params: FittedParams | None = None,
        **kwargs: Any,
    ) -> None:
        """``params`` (a person drawn from ``population``), or its fields as keywords."""
        params = params if params is not None else FittedParams(**kwargs)
        super().__init__(task, theta_star, rng, sigma=sigma, bias=bias, params=params)
        self.params: FittedParams = params
        self.made = 0
        """Corrections pushed (released) so far this session."""
        self.intended: list[np.ndarray] = []
        """Every push's intended correction (a_max units), as drawn: what v2's arm reads of
        them is measured against these (``participant_check``'s read scale)."""
        reactive = params.hazard is not None
        self.needs_theta_hat = reactive
        """A reactive person (``hazard``) judges the plan the robot plays: it is handed θ̂."""
        self.done_at: float | None = 0.0 if params.budget == 0 and not reactive else None
        self._t_next = params.rest
        self._last_release = 0.0
        self._shortfalls: dict[bytes, float] = {}
        self._push_wrench = (np.zeros(3), np.zeros(3))
        self._started = 0.0
        self._pushed = 0.0
        self._watched_last = 0.0

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: Any = None) -> np.ndarray:
        """A correction drawn at pose ``x`` from this person's fitted aim and sizes (or the
        aimed person's, ``params.correction``)."""
        del u_r, theta_hat
        p = self.params
        if p.correction == "aimed":
            u = aimed_correction(self.task, self._theta_star, x, self.rng)
            self.intended.append(u)
            return u * self._a_max
        best = best_correction(self.task, self._theta_star, x)
        u = draw_corrections(
            best,
            self.rng,
            aim=p.aim,
            size=p.size,
            size_within=p.size_within,
            turn=p.turn,
            turn_within=p.turn_within,
        )[0]
        self.intended.append(u)
        return u * self._a_max

    def _target(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """x + u, its position kept within the planning box widened to hold the cup: a face
        the cup is already past does not pull the target back (the Task's step would: at v2's
        corner [0.25, 0.65, 0.08], outside the box's y ≤ 0.6, it turned pushes towards θ*'s
        best into pushes away from it; docs/study.md)."""
        x = np.asarray(x, dtype=np.float64)
        target = self.task.dynamics(x, u, np.zeros_like(u))
        low = np.minimum(np.asarray(self.task.low, dtype=np.float64)[:3], x[:3])
        high = np.maximum(np.asarray(self.task.high, dtype=np.float64)[:3], x[:3])
        target[:3] = np.clip(x[:3] + u[:3], low, high)
        return target

    def _decide(self, t: float, x: np.ndarray, theta_hat: Any) -> np.ndarray | None:
        if self.params.hazard is not None:
            return self._decide_reactive(t, x, theta_hat)
        if self.made >= self.params.budget:
            return None
        return super()._decide(t, x, theta_hat)

    def _decide_reactive(self, t: float, x: np.ndarray, theta_hat: Any) -> np.ndarray | None:
        """The fitted timing hazard (``FittedParams.hazard``): every ``decide_every`` s it
        steps in with probability 1 − exp(−rate·decide_every), rate from the shortfall of the
        plan of the robot's θ̂ and the time since its last correction; it pushes ``reaction``
        s later from what it sees then. Done after ``path_time`` s of the robot's motion, or
        when that motion plus the motion before its last push reach ``doubled_budget``."""
        p = self.params
        if self._push_at is not None:
            if t + 1e-9 < self._push_at:
                return None
            self._push_at = None
            return self._target(x, self.act(x, np.zeros(self.task.action_dim)))
        if self.done_at is not None or t + 1e-9 < self._t_next:
            return None
        self._t_next = t + p.decide_every
        motion = t - self._pushed
        if motion >= p.path_time or motion + self._watched_last >= p.doubled_budget:
            self.done_at = t
            return None
        assert p.hazard is not None
        rate = hazard_rate(p.hazard, self.shortfall(theta_hat), t - self._last_release)
        self.judgments += 1
        if self.rng.random() < step_in_probability(rate, p.decide_every):
            self.rejections += 1
            self._push_at = t + p.reaction
            if p.reaction <= 0.0:
                return self._decide_reactive(t, x, theta_hat)
        return None

    def shortfall(self, theta_hat: Any) -> float:
        """The shortfall of the plan of the robot's θ̂ under its θ* (``timing.shortfall``;
        computed once per θ̂)."""
        if theta_hat is None:
            raise ValueError("a reactive participant (hazard) needs the robot's theta_hat")
        th = np.asarray(theta_hat, dtype=np.float64)
        key = th.tobytes()
        if key not in self._shortfalls:
            self._shortfalls[key] = float(shortfall(self.task, self._theta_star, th)[0])
        return self._shortfalls[key]

    def wrench(
        self, t: float, x: np.ndarray, theta_hat: Any = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """As ``Participant.wrench``, but pushing as hard as the intended displacement needs
        (``feel``; at least ``min_felt``, at most ``push_force``), and a release ramps the
        push's own wrench down."""
        before = self.phase
        f, tq = super().wrench(t, x, theta_hat)
        if self.phase == "push":
            if before != "push":
                self._started = t
                self._sizing = self._push_sizes(x)
            force, torque = self._sizing
            f = f * (force / self.params.push_force)
            tq = tq * (torque / self.params.push_torque)
            self._push_wrench = (f, tq)
        elif self.phase == "release":
            start = self._t0 if before == "release" else t
            level = max(0.0, 1.0 - (t - start) / self.params.ramp)
            f, tq = self._push_wrench[0] * level, self._push_wrench[1] * level
        return f, tq

    def _push_sizes(self, x: np.ndarray) -> tuple[float, float]:
        """(force N, torque N m) of the push that begins at pose ``x``: ``feel`` times the
        intended displacement and turn, capped, and raised together to ``min_felt``."""
        p = self.params
        dp, dr = self._error(x)
        force = min(p.push_force, p.feel * float(np.linalg.norm(dp)))
        torque = min(p.push_torque, p.feel_rot * float(np.linalg.norm(dr)))
        felt = force + torque / TORQUE_LEVER
        if 0.0 < felt < p.min_felt:
            scale = p.min_felt / felt
            force, torque = min(p.push_force, force * scale), min(p.push_torque, torque * scale)
        return force, torque

    def _released(self, t: float, x: np.ndarray) -> None:
        super()._released(t, x)
        self.made += 1
        watched = self._started - self._pushed  # the robot's path time before this push
        self._pushed += t - self._started
        self._last_release = t
        self._watched_last = watched
        if self.params.hazard is None and self.made >= self.params.budget:
            self.done_at = t + self.params.linger * watched
