"""StROL-Study-v1: the user study with u_H = the person's push, the Panda's limits and a reflex.

What changes from v0 (``strol_gym.envs.study``), and why (measurements in ``docs/study.md``):

- **Tracking.** The impedance law gains integral action (frozen while a person pushes, so the
  arm stays as compliant as v0's) and a feedforward of the joints' viscous damping along the
  setpoint's motion, so the cup stays on its setpoint while it follows a plan; holding the
  setpoint then moves nothing.
- **u_H is measured against the rest pose.** While a correction lasts the setpoint is held; the
  held arm would rest there. u_H = the cup's pose when the push ends minus the held setpoint
  (``info["correction_state"]`` is that setpoint), so whatever the arm was still doing on its
  own (catching up, stopping) is not read as the person's push. Where the setpoint is out of
  reach (the cup more than 1 cm from it when the push begins: a stretched elbow, a joint
  limit, a contact) the arm would rest where it is, and u_H is measured from the cup's pose.
- **A reachable planning box.** The robot executes θ̂'s plan clipped to where the arm reaches
  the cup with its wrist free and above the pitcher and the plate (``within_reach``): the
  Task's own box let many θ̂ ask for poses beyond the elbow's reach, where the cup stopped
  centimetres short of its setpoint. The regret is still the Task's (its planner and box).
- **The Panda's datasheet limits.** Joint torques are clipped to 87 N m (joints 1-4) and
  12 N m (5-7) by the actuators' control range; joint speeds are held at 2.175 rad/s (1-4) and
  2.61 rad/s (5-7) after every physics step once any joint passes half its limit.
- **A Cartesian force reflex.** An external force above ``reflex_force`` (100 N) or torque above
  ``reflex_torque`` (10 N m) at the cup brakes the arm: the joints are locked where they are
  (the real Panda's brakes; torque-limited motors could not hold 200 N at the cup).
  ``info["reflex"]`` is True on the step it trips, ``info["braked"]`` while the brakes hold.
  A correction under way is dropped: no u_H comes from a shove (its seconds still count in
  ``correction_time``, the person did push). The brakes release ``reflex_recover`` seconds after
  the felt wrench falls below ``force_threshold``; the robot then replans from where it stands.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import mujoco
import numpy as np

from strol_gym.envs.panda.model import N_ARM
from strol_gym.envs.study.participant import Participant
from strol_gym.envs.study.scene import JOINT_DAMPING
from strol_gym.envs.study.user import SimulatedUser, angle_delta
from strol_gym.envs.study.v0 import HOLD, TORQUE_LEVER, StudyEnv, Velocity, _positive
from strol_gym.tasks.study import CONTROL_DT, PITCHER, StudyTask

VELOCITY_LIMIT = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
"""The Panda's joint speed limits (rad/s, datasheet)."""
TORQUE_LIMIT = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])
"""The Panda's joint torque limits (N m, datasheet)."""
K_INTEGRAL = (10.0, 10.0)
"""Integral gains of the impedance law, as multiples of the stiffness (1/s): position, rotation."""
INTEGRAL_MAX = (8.0, 0.8)
"""Bounds of the integral wrench per axis (N, N m): it can cancel a few newtons of unmodelled
force (joint friction, the elbow's pull), never fight a person."""
K_NULL, D_NULL = 0.5, 0.5
REST_TRUST = 0.01
"""m: beyond this lag at a correction's start, u_H is measured from the cup's pose (v0's way)."""
MODEL_EVERY = 4
"""Control steps between refreshes of Λ, D and the null-space projector (0.2 s)."""
_ZERO6 = [0.0] * 6
LAMBDA_REG = 1e-2 * np.eye(6)
"""Added to J M⁻¹ Jᵀ before inverting it: near a singular pose Λ stays ≤ ~100 kg."""
REACH_LOW = np.array([0.25, -0.45, 0.20])
REACH_HIGH = np.array([0.70, 0.55, 0.60])
"""The planning box the robot executes within (m): the cup stays where the arm reaches it with
the wrist free, its bottom (10 cm below the rim) clear of the plate's riser (docs/study.md
measures it; the pitcher has its own keep-out zone, ``PITCHER_CLEAR``)."""
REACH_ANGLE = 1.0
"""|roll|, |pitch| the executed plan may reach (rad): beyond it the wrist binds far from home."""
SHOULDER = np.array([0.0, 0.0, 0.333])
REACH_RADIUS = 0.70
"""m from the shoulder (joint 2's axis) the cup may go: the stretched elbow (joint 4 at its
limit) leaves the cup short of setpoints beyond about 0.75 m."""
"""|roll|, |pitch| the executed plan may reach (rad): beyond it the wrist binds far from home."""
PITCHER_CLEAR = (0.14, 0.37)
"""The pitcher's keep-out zone for the cup (m): within 0.14 m of its axis (its 7 cm radius, the
cup's 4 cm and 3 cm to spare) the cup's rim stays above 0.37 m (the pitcher's 24 cm, the cup's
10 cm below its rim and 3 cm to spare)."""
PARTICIPANTS = ("observer", "oracle")
"""``observer``: ``Participant``, who judges the cup's motion under its θ* (held out: no shipped
ĝ was trained on its corrections); ``oracle``: v0's ``SimulatedUser`` with the human model
(``human``, default eq. M6, the training human), satisfied by the plan's regret."""


class StudyEnvV1(StudyEnv):
    """StROL-Study-v1: ``StudyEnv`` (v0) with u_H = the person's push, the Panda's joint limits
    and a Cartesian force reflex (see the module docstring and ``docs/study.md``).

    Extra arguments: ``participant`` ("observer", default, or "oracle"; ``PARTICIPANTS``; the
    simulated person when ``human`` is not None), ``reflex_force`` (N, > 0, default 100),
    ``reflex_torque`` (N m, > 0, default 10), ``reflex_recover`` (s, > 0, default 0.5).
    Extra ``info``: ``reflex`` (the reflex tripped this step), ``braked``, ``reflexes`` (count
    this episode), ``lag`` (the cup's distance to its setpoint, m), ``gave_up`` (1.0 once the
    participant has given up, else 0.0). ``pause(seconds)`` holds
    the setpoint where it is.

    ## Version History

    - v1: u_H measured against the held setpoint, integral and damping feedforward in the
      impedance law, joint speed and torque limits, the force reflex, ``pause``.
    - v0: initial version (kept, deprecated, for the published results).
    """

    env_id: ClassVar[str] = "StROL-Study-v1"
    reach: tuple[np.ndarray, np.ndarray, float] | None = (REACH_LOW, REACH_HIGH, REACH_ANGLE)
    """The box the executed plans stay in (``within_reach``; None: the Task's plans as they are)."""

    def __init__(
        self,
        task: Any = 1,
        *,
        reflex_force: float = 100.0,
        reflex_torque: float = 10.0,
        reflex_recover: float = 0.5,
        participant: str = "observer",
        **kwargs: Any,
    ) -> None:
        if participant not in PARTICIPANTS:
            raise ValueError(
                f"participant must be one of {sorted(PARTICIPANTS)}, got {participant!r}"
            )
        self.participant = participant
        self.reflex_force = _positive("reflex_force", reflex_force)
        self.reflex_torque = _positive("reflex_torque", reflex_torque)
        self.reflex_recover = _positive("reflex_recover", reflex_recover)
        super().__init__(task, **kwargs)

    def _new_user(self, theta_star: np.ndarray, rng: np.random.Generator) -> SimulatedUser:
        if self.participant == "oracle":
            return super()._new_user(theta_star, rng)
        return Participant(
            self.task, theta_star, rng, sigma=self.sigma, bias=self.bias, **self.user_kwargs
        )

    # ------------------------------------------------------------------ model and state
    def _build(self) -> None:
        super()._build()
        # The actuators' control range already clips torques; make it the datasheet's (a copy
        # of the cached model would cost more than checking it is so).
        if not np.allclose(np.abs(self.model.actuator_ctrlrange[:N_ARM]).max(1), TORQUE_LIMIT):
            raise RuntimeError("the Panda model's torque range is not the datasheet's")
        self._mass = np.zeros((self.model.nv, self.model.nv))
        self._eye7 = np.eye(N_ARM)
        kp, kr = self._k[0], 2.0 * self._k[1]  # v0's rotation term is 2 kr' sin: kr = 2 kr'
        self._sqrt_k = np.sqrt([kp, kp, kp, kr, kr, kr])
        self._vlim = VELOCITY_LIMIT.tolist()
        self._half_vlim = (0.5 * VELOCITY_LIMIT).tolist()

    def _reset_sim(self) -> None:
        super()._reset_sim()
        self._integral = [0.0] * 6
        self._v_prev = _ZERO6
        self._model_age = 0
        self._v_feed: list[float] | None = None
        self._braked = False
        self._brake_q = self._qpos.copy()
        self._release_at = math.inf
        self._reflex = False
        self._n_reflex = 0
        self._pause_until = -1.0
        self._rest_x = self._x.copy()

    def _set_plan(self, waypoints: np.ndarray, leg: str) -> None:
        """Plans for θ̂ are clipped to the reachable box (``within_reach``); the way home is
        reachable as it is."""
        if leg == "plan" and self.reach is not None:
            waypoints = within_reach(self.task, waypoints, *self.reach)
        super()._set_plan(waypoints, leg)

    def pause(self, seconds: float) -> None:
        """Hold the setpoint where it is for ``seconds`` (the robot waits, then goes on)."""
        self._pause_until = self._time + _positive("seconds", seconds) - 1e-9

    # ------------------------------------------------------------------ step
    def _move_setpoint(self, u_r: np.ndarray) -> tuple[np.ndarray, Velocity]:
        if self._braked or self._time < self._pause_until:
            return self._zeros, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        return super()._move_setpoint(u_r)

    def _transition(self, u_res: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, dict]:
        self._reflex = False
        u_h, u_r, is_correction, info = super()._transition(u_res)
        info.update(
            reflex=self._reflex,
            braked=self._braked,
            reflexes=self._n_reflex,
            lag=math.dist(self._sp[:3].tolist(), self._x[:3].tolist()),
            gave_up=float(getattr(self.human, "gave_up", False)),
        )
        return u_h, u_r, is_correction, info

    def _external_wrench(self) -> np.ndarray:
        """The summed wrench, and the reflex's decision on it (before the physics runs)."""
        w = super()._external_wrench()
        fx, fy, fz, tx, ty, tz = w.tolist()
        force, torque = math.hypot(fx, fy, fz), math.hypot(tx, ty, tz)
        if force > self.reflex_force or torque > self.reflex_torque:
            if not self._braked:
                self._trip()
            self._release_at = math.inf
        elif self._braked:
            felt = force + torque / TORQUE_LEVER
            if felt > self.force_threshold:
                self._release_at = math.inf
            elif self._release_at == math.inf:
                self._release_at = self._time + self.reflex_recover - 1e-9
            elif self._time >= self._release_at:
                self._release()
        return w

    def _pushing(self, felt: float) -> bool:
        return felt > self.force_threshold and not self._braked  # braked: no correction

    def _trip(self) -> None:
        self._braked, self._reflex = True, True
        self._n_reflex += 1
        self._brake_q = self._qpos.copy()
        self._qvel_all[:] = 0.0
        self._active = False  # the shove is no correction
        self._integral = [0.0] * 6

    def _release(self) -> None:
        self._braked = False
        self._release_at = math.inf
        self._replan()

    def _correction_start(self) -> np.ndarray:
        """Where the held arm would rest: its setpoint, unless the cup is more than
        ``REST_TRUST`` from it (a setpoint beyond reach or behind an obstacle, where the arm
        rests short of it): then the cup's pose, as in v0."""
        if math.dist(self._sp[:3].tolist(), self._x[:3].tolist()) > REST_TRUST:
            return self._x.copy()
        return self._sp.copy()

    # ------------------------------------------------------------------ physics
    def _model_terms(self, v_sp: np.ndarray) -> None:
        """The model-based terms of the control law, at the current pose: the cup's
        task-space inertia Λ, the damping D = √K Λ^½ + Λ^½ √K (critical for the arm's real
        inertia, which v0's scalar gains underestimate 2-5x) and the null-space projector N,
        folded into joint-space matrices (refreshed every ``MODEL_EVERY`` control steps: the
        pose changes little in between); and, when the setpoint's velocity changes, its
        acceleration feedforward Λ a_sp and the torques that move along it (Jᵀ D v_sp and the
        joints' viscous damping at J̄ v_sp, J̄ = M⁻¹ Jᵀ Λ)."""
        refresh = self._model_age <= 0
        if refresh:
            self._model_age = MODEL_EVERY
            ja = self._jac[:, :N_ARM]
            mujoco.mj_fullM(self.model, self.data, self._mass)
            m_inv_jt = np.linalg.solve(self._mass[:N_ARM, :N_ARM], ja.T)
            lam = np.linalg.inv(ja.dot(m_inv_jt) + LAMBDA_REG)
            vals, vecs = np.linalg.eigh(lam)
            root = (vecs * np.sqrt(np.maximum(vals, 0.0))).dot(vecs.T)
            jt_damp = ja.T.dot(root * self._sqrt_k + self._sqrt_k[:, None] * root)
            # The elbow's pull acts in the task's null space only (N = I − Jᵀ J̄ᵀ): v0's pull,
            # unprojected, turned the wrist off its setpoint by up to 0.05 rad.
            null = self._eye7 - ja.T.dot(lam.dot(m_inv_jt.T))
            # τ = Jᵀ(K e + ∫ + Λ a_sp) + c − G [q; q̇]: G = [K_n N, Jᵀ D J + D_n N].
            self._gain = np.hstack([K_NULL * null, jt_damp.dot(ja) + D_NULL * null])
            self._pull_home = (K_NULL * null).dot(self._q_home)
            self._lam, self._dyn_inv, self._jt_damp = lam, m_inv_jt.dot(lam), jt_damp
        self._model_age -= 1
        v_list = v_sp.tolist()
        if v_list == self._v_prev:
            self._acc_ff = _ZERO6
        else:
            acc = (v_sp - np.array(self._v_prev)) * (1.0 / CONTROL_DT)
            self._acc_ff = self._lam.dot(acc).tolist()
            self._v_prev = v_list
        if refresh or v_list != self._v_feed:
            self._v_feed = v_list
            feed = self._jt_damp.dot(v_sp) + JOINT_DAMPING * self._dyn_inv.dot(v_sp)
            self._const = (feed + self._pull_home).tolist()

    def _simulate(self, v_sp: Velocity) -> None:
        """One control step: τ = Jᵀ(K e + D (v_sp − J q̇) + Λ a_sp + ∫) + the joints' damping
        fed forward + a weak pull to the home joints in the null space, recomputed every
        ``HOLD`` physics steps; the integral ∫ (bounded) is frozen while a correction lasts;
        joint speeds are held at the limits. While braked the joints stay locked (nothing
        else in the scene moves, so no physics runs)."""
        m, d = self.model, self.data
        if self._braked:
            self._qpos[:] = self._brake_q
            self._qvel_all[:] = 0.0
            self._hand_xfrc[:] = 0.0
            self._v_prev = _ZERO6
            self._model_age = 0
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            self._time += CONTROL_DT
            return
        self._push_at_cup()
        jac, jp, jr, ctrl, site = self._jac, self._jacp, self._jacr, self._ctrl, self._site
        q, qd = self._qpos, self._qvel
        xpos, xmat_t, sp_r = self._site_xpos, self._site_xmat.T, self._sp_R
        (spx, spy, spz), kp, kr = self._sp[:3].tolist(), self._k[0], 2.0 * self._k[1]
        vx, vy, vz, wx, wy, wz = v_sp
        integrate = not self._active
        dt_i = HOLD * self.model.opt.timestep
        gp, gr = kp * K_INTEGRAL[0] * dt_i, kr * K_INTEGRAL[1] * dt_i
        ip, ir = INTEGRAL_MAX
        vlim, half = self._vlim, self._half_vlim
        for i in range(self._n_sub // HOLD):
            mujoco.mj_jacSite(m, d, jp, jr, site)
            if i == 0:
                self._model_terms(np.array(v_sp))
            x, y, z = xpos.tolist()
            (_, r01, r02), (r10, _, r12), (r20, r21, _) = sp_r.dot(xmat_t).tolist()
            # The setpoint where it is at this chunk's start (it moves linearly over the
            # step): a staircase setpoint would put the cup ¾ of a step ahead of it.
            back = CONTROL_DT - i * dt_i
            e = (
                spx - vx * back - x,
                spy - vy * back - y,
                spz - vz * back - z,
                0.5 * (r21 - r12) - wx * back,
                0.5 * (r02 - r20) - wy * back,
                0.5 * (r10 - r01) - wz * back,
            )
            integ = self._integral
            if integrate:
                integ = [
                    min(ip, max(-ip, a + gp * b)) for a, b in zip(integ[:3], e[:3], strict=False)
                ] + [min(ir, max(-ir, a + gr * b)) for a, b in zip(integ[3:], e[3:], strict=False)]
                self._integral = integ
            w = np.array(
                [
                    k * a + b + c
                    for k, a, b, c in zip(
                        (kp, kp, kp, kr, kr, kr), e, integ, self._acc_ff, strict=False
                    )
                ]
            )
            rest = self._gain.dot(np.concatenate((q, qd))).tolist()
            joints = zip(w.dot(jac).tolist(), self._const, rest, strict=False)
            ctrl[:] = [t + c - g for t, c, g in joints]
            if any(abs(s) > h for s, h in zip(qd.tolist(), half, strict=False)):
                for _ in range(HOLD):  # near a speed limit: hold it every physics step
                    mujoco.mj_step(m, d)
                    qd[:] = np.clip(qd, -VELOCITY_LIMIT, VELOCITY_LIMIT)
            else:
                mujoco.mj_step(m, d, HOLD)
                if any(abs(s) > lim for s, lim in zip(qd.tolist(), vlim, strict=False)):
                    qd[:] = np.clip(qd, -VELOCITY_LIMIT, VELOCITY_LIMIT)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        self._time += CONTROL_DT


def within_reach(
    task: StudyTask, plan: np.ndarray, low: np.ndarray, high: np.ndarray, angle: float
) -> np.ndarray:
    """``plan`` (T+1, s) with every waypoint after the first moved into the box (positions in
    [low, high], within ``REACH_RADIUS`` of the shoulder and out of the pitcher's keep-out zone
    (``PITCHER_CLEAR``: lifted over it), |roll|, |pitch| ≤ ``angle``; yaw as planned), each
    step still within the planner's bounds (``plan_pos_bound``, ``plan_ang_bound`` per axis):
    a start outside the box (where a person left the cup) is left at the planner's pace, not in
    one jump.

    The Task's planning box lets θ̂ ask for poses the arm cannot reach, or that put the cup into
    the table, the plate or the pitcher: there the cup stops centimetres short of its setpoint
    and drifts while the arm settles at its boundary. The regret is still the Task's (its
    planner, its box): this box is what the robot executes."""
    plan = np.asarray(plan, dtype=np.float64)
    lo, hi = low.tolist(), high.tolist()
    step = [task.plan_pos_bound] * 3
    if task.oriented:
        lo, hi = [*lo, -angle, -angle, -math.inf], [*hi, angle, angle, math.inf]
        step += [task.plan_ang_bound] * 3
    lo_a, hi_a, step_a = np.array(lo), np.array(hi), np.array(step)
    out = plan.copy()
    for i in range(1, len(plan)):
        goal = np.clip(plan[i], lo_a, hi_a)
        arm = goal[:3] - SHOULDER
        far = float(np.linalg.norm(arm))
        if far > REACH_RADIUS:
            goal[:3] = SHOULDER + arm * (REACH_RADIUS / far)
        if _over_pitcher(goal):
            goal[2] = PITCHER_CLEAR[1]  # above it, where the xy distance is the same
        move = angle_delta(goal, out[i - 1])
        out[i] = out[i - 1] + np.clip(move, -step_a, step_a)
        if _over_pitcher(out[i]):  # rise first, then move in over it
            out[i, :2] = out[i - 1, :2]
    return out


def _over_pitcher(x: np.ndarray) -> bool:
    """Whether the cup at ``x`` would be in the pitcher's keep-out zone (``PITCHER_CLEAR``)."""
    near = math.hypot(x[0] - PITCHER[0], x[1] - PITCHER[1]) < PITCHER_CLEAR[0]
    return near and x[2] < PITCHER_CLEAR[1]


__all__ = ["TORQUE_LIMIT", "VELOCITY_LIMIT", "StudyEnvV1", "within_reach"]
