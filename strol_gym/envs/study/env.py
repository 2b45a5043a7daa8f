"""StROL-Study: the paper's user study in simulation, a compliant Panda that people push.

One env class for every version: :class:`StudyEnv` reads what its version changes from its
``version`` (a :class:`~strol_gym.envs.study.versions.StudyVersion`); ``StudyEnv`` itself is
v0 (as published), :class:`StudyEnvV1` and :class:`StudyEnvV2` name v1 and v2 (each version's
``env_class``, registered from ``versions.VERSIONS``). The controllers are in ``controller``, the
pose helpers in ``geometry``, the people who push in ``user`` and ``participant``.
"""

from __future__ import annotations

import functools
import math
from typing import Any, ClassVar, cast

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from strol_gym import checks
from strol_gym.envs.contract import CorrectionEnv, int_arg, render_metadata, vector_arg
from strol_gym.envs.panda.model import FINGER_OPEN, N_ARM, MujocoRendering
from strol_gym.envs.study import persons
from strol_gym.envs.study.admittance import REST
from strol_gym.envs.study.controller import _INSTABILITY, ImpedanceController, Velocity
from strol_gym.envs.study.geometry import angle_delta, rotation_error, straight, within_reach
from strol_gym.envs.study.people import TORQUE_LEVER, HeldWrench, ScriptedWrench
from strol_gym.envs.study.persons import StudyPerson
from strol_gym.envs.study.scene import build_model, model_q
from strol_gym.envs.study.segment import HOLD_OFF_RANGE, PushSegmenter
from strol_gym.envs.study.versions import PARTICIPANTS, REST_TRUST, V0, V1, V2, StudyVersion
from strol_gym.humans.spec import DEFAULT_PERSON, HumanSpec, person_spec
from strol_gym.priors import Prior
from strol_gym.tasks import make_task
from strol_gym.tasks.study import (
    CONTROL_DT,
    SEGMENT_TIME,
    StudyTask,
    StudyTaskV2,
    mat_to_rpy,
    rpy_to_mat,
)

END_HOLD = 2.0
"""Seconds the robot waits at the end of its plan before it returns home and plays it again."""
_F32_MAX = float(np.finfo(np.float32).max)
_STILL: Velocity = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


class StudyEnv(ImpedanceController, MujocoRendering, CorrectionEnv, gym.Env):
    """StROL-Study-v0: a compliant Franka Panda carries a cup; a person's pushes teach it θ*.

    ## Description

    The paper's user study (StROL, RA-L 2024, "User Study") with physics: a 7-DoF Panda
    (gymnasium-robotics' model files) holds a cup over a table with a pitcher at (0.35, 0.10, 0)
    and a plate at (0.70, −0.45, 0.10) (robot base frame, m). The robot follows a plan for its
    estimate θ̂ (``task.plan``: waypoints ≤ 0.05 m and ≤ 0.1 rad apart, one per 0.5 s) through a
    Cartesian impedance controller in joint torques (``docs/study.md``), so a push on the hand
    moves it and the arm returns to the plan when released. A **correction** is an interval in
    which the external force on the hand exceeds ``force_threshold`` (15 N); when it ends, u_H
    = the cup's pose change over it (3-D position for Task 1, 6-D pose for Tasks 2-3). The
    robot holds its setpoint while it is pushed and replans (from where it is) whenever θ̂
    changes. At the end of a plan it waits 2 s, returns home and plays its current plan again.

    External wrenches come from three sources, summed each step: the simulated person
    (``person``; ``env.person`` this episode), ``apply_wrench`` (scripted, for a duration)
    and ``hold_wrench`` (held until changed: what an interactive front end writes after
    reading the viewer's perturbation).
    The env does not know which one pushed.

    ## Action Space

    ``Box(-1, 1, (a,), float32)``, a = 3 (Task 1) or 6: a residual velocity added to the
    planned setpoint's, scaled by ``task.robot_action_bound`` (0.005 m and 0.01 rad per step,
    i.e. 0.1 m/s and 0.2 rad/s). Zeros reproduce the paper's robot. Clipped to [−1, 1]; NaN
    raises ``ValueError``. Ignored while a correction is active (the setpoint is held).

    ## Observation Space

    ``Dict`` of float32 Boxes: ``"state"`` (3 or 6): the cup's pose (position, and roll, pitch,
    yaw for Tasks 2-3); ``"correction"``: u_H on the step a correction ended, else zeros;
    ``"theta_hat"``: θ̂; ``"phi"``: φ(state); ``"wrench"`` (6,): the external force (N) and
    torque (N m) on the hand this step (clipped to float32's finite range).

    ## Rewards

    θ*·φ(x') (the study participant's reward). ``info``: the shared keys (``features``,
    ``phi``, ``correction``, ``robot_action`` = the setpoint's displacement this step (zeros
    while held), ``theta_star``, ``theta_hat``, ``is_correction``) plus ``u_h``,
    ``correction_active``, ``correction_time`` (seconds pushed so far this episode),
    ``corrections`` (count), ``time``, ``wrench``, ``unstable``; on the step a correction ends
    ``correction_state`` (the pose where it began) and ``correction_record`` (start and end
    time, start pose, u_H, and the wrench trace: times, forces, torques). Wrapped in
    ``OnlineLearningWrapper``, the last step adds ``error`` and ``regret``.

    ## Starting State

    The Task's home joints (paper), arm at rest. θ* is the Task's (the issue's table) unless
    ``reset(options={"theta_star": ...})``; θ̂0 ~ U[−1, 1]^d from ``env.np_random``
    (``info["theta_hat0"]``; the wrapper starts its learner there); the simulated user's
    generator is drawn from ``env.np_random`` next.

    ## Episode End

    Never terminates. Truncated after ``duration`` seconds of simulated time (60 s = 1200
    steps; ``gymnasium.make(..., max_episode_steps=N)`` shortens it), or at once with
    ``info["unstable"] = True`` if the simulation becomes unstable (a MuJoCo warning or NaN);
    the observation is then the last finite one.

    ## Arguments

    - ``task`` (1 | 2 | 3, a ``StudyTask`` or its registered name; default 1).
    - ``person``: who pushes (``strol_gym.envs.study.persons``). Omitted: the version's default
      (v0: ``"oracle"``, the regret-judging user correcting as eq. M6 wants). A name: the
      version's people (v1: ``"observer"``, ``"oracle"``; v2 also ``"fitted"``) or a human
      model's name (the oracle with that model); or ``HumanSpec(name, sigma=, bias=, beta=,
      kwargs=)`` (or a dict of those fields): σ, ε (fractions of a_max = 0.1 m, 0.3 rad) and β
      where the person uses them, ``kwargs`` its own parameters (the oracle's: the model's and
      ``push_force``, ``push_torque``, ``ramp``, ``max_push``, ``decide_every``, ``rest``,
      ``min_correction``, ``tol``, ``ang_tol``, ``satisfied_regret``;
      ``strol_gym.envs.study.user``). A value the person does not use raises ValueError
      naming it. ``None``: no simulated person (scripted or a real person's pushes only).
    - ``prior`` (None = the Task's multimodal prior, "uniform", a ``Prior`` or modes).
    - ``force_threshold`` (N, > 0, default 15), ``hold_off`` (v2 only: s in [0, 0.5], default
      0.4; how long the force must stay at or below the threshold for a correction to end),
      ``duration`` (s, > 0, default 60),
      ``stiffness`` (N/m, > 0, default 400; v2: 300), ``rot_stiffness`` (N m/rad, > 0,
      default 30; v2: 10).
    - ``max_episode_steps`` (int ≥ 1 or None), ``render_mode`` (None | "rgb_array" |
      "human"), ``width``, ``height``.

    ## Version History

    - v2 (``StudyEnvV2``): u_H by counterfactual, an admittance layer, plans within reach
      and outside the objects, one push one correction, the fitted population. Use it.
    - v1 (``StudyEnvV1``): u_H is measured from the held setpoint, tracking that makes the
      arm's catch-up negligible, the Panda's joint limits, a force reflex, and a participant
      who judges what it sees (deprecated).
    - v0: initial version; kept unchanged for the published results (deprecated).
    """

    metadata: dict[str, Any] = render_metadata(fps=20)
    version: ClassVar[StudyVersion] = V0
    """What this version changes (``strol_gym.envs.study.versions``); a subclass names its
    version and nothing else (``env_id`` and ``reach`` follow from it)."""
    env_id: ClassVar[str] = V0.env_id
    reach: tuple[np.ndarray, np.ndarray, float] | None = V0.reach
    """The box the executed plans stay in (``within_reach``; None: the Task's plans as they
    are); the version's, settable per env."""

    task_cls: ClassVar[type[StudyTask]] = StudyTask
    default_corrections: ClassVar[int] = 0
    """The simulated user corrects when it chooses, not on the first steps."""

    def __init__(
        self,
        task: int | StudyTask | str = 1,
        *,
        person: Any = DEFAULT_PERSON,
        prior: str | Prior | Any | None = None,
        force_threshold: float = 15.0,
        duration: float = 60.0,
        stiffness: float | None = None,
        rot_stiffness: float | None = None,
        reflex_force: float | None = None,
        reflex_torque: float | None = None,
        reflex_recover: float | None = None,
        hold_off: float | None = None,
        **kwargs: Any,
    ) -> None:
        """The arguments of the env's docstring; ``reflex_*`` and ``hold_off`` only where the
        version has them (None: its default)."""
        v = self.version
        extra = {"reflex_force": reflex_force, "reflex_torque": reflex_torque}
        extra |= {"reflex_recover": reflex_recover}
        given = sorted(k for k, x in extra.items() if x is not None) if not v.reflex else []
        if hold_off is not None and v.hold_off is None:
            given.append("hold_off")
        if given:
            raise ValueError(f"unknown argument(s) {given}; {self.env_id} has none of them")
        self.person: StudyPerson | None = None
        """This episode's simulated person (None: nobody simulated pushes)."""
        low, high = HOLD_OFF_RANGE
        self.hold_off = (
            0.0
            if v.hold_off is None
            else float(
                checks.number(
                    "hold_off",
                    v.hold_off if hold_off is None else hold_off,
                    low=low,
                    high=high,
                    text=True,
                )
            )
        )
        """Seconds the felt force must stay at or below the threshold for a correction to end
        (``segment.PushSegmenter``; 0 on versions without a hold-off)."""
        self.reflex_force = _within(
            "reflex_force", 100.0 if reflex_force is None else reflex_force, REFLEX_FORCE_RANGE
        )
        self.reflex_torque = _within(
            "reflex_torque", 10.0 if reflex_torque is None else reflex_torque, REFLEX_TORQUE_RANGE
        )
        self.reflex_recover = _positive(
            "reflex_recover", 0.5 if reflex_recover is None else reflex_recover
        )
        if "n_corrections" in kwargs:
            raise ValueError(
                f"unknown argument(s) ['n_corrections']; {self.env_id}'s simulated user corrects "
                "when it chooses"
            )
        self.force_threshold = _positive("force_threshold", force_threshold)
        self.duration = _positive("duration", duration)
        self.stiffness = _positive("stiffness", v.stiffness if stiffness is None else stiffness)
        self.rot_stiffness = _positive(
            "rot_stiffness", v.rot_stiffness if rot_stiffness is None else rot_stiffness
        )
        super().__init__(task=task, prior=prior, person=person, **kwargs)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls.env_id, cls.reach = cls.version.env_id, cls.version.reach

    def _make_task(self, task: Any) -> StudyTask:
        """1, 2 or 3 (the paper's Tasks), a ``StudyTask`` or its registered name."""
        if isinstance(task, int | np.integer) and not isinstance(task, bool):
            return self.version.numbered[int_arg("task", task, 1, 3)]()
        if not isinstance(task, StudyTask | str):
            raise ValueError(f"task must be 1, 2 or 3 (or a StudyTask), got {task!r}")
        return make_task(task, of=StudyTask)

    @classmethod
    def resolve_person(cls, person: Any) -> HumanSpec | None:
        """The ``person=`` argument as this version uses it (``persons.as_used``)."""
        participants = cls.version.participants
        spec = person_spec(person, persons.default_person(participants))
        return None if spec is None else persons.as_used(spec, participants)

    @property
    def user_enabled(self) -> bool:
        """Whether a simulated person pushes (``person`` not None)."""
        return self.person_spec is not None

    @property
    def theta_star(self) -> np.ndarray:
        """The person's current preference θ* (the Task's when nobody simulated pushes)."""
        person = self.person
        if person is not None:
            return np.asarray(person.theta_star, dtype=np.float64)
        return self._theta_star

    @theta_star.setter
    def theta_star(self, value: np.ndarray) -> None:
        self._theta_star = np.asarray(value, dtype=np.float64)

    def _setup(self) -> None:
        self.task: StudyTask
        if self.person_spec is not None:  # fail at construction, not at the first reset
            persons.build(
                self.person_spec, self.task, self.task.theta_star, np.random.default_rng(0)
            )
        t = self.task
        f32 = np.float32
        lim = np.array([2.0] * 3 + [4.0] * (t.state_dim - 3), dtype=f32)
        self.observation_space = self._observation_space(spaces.Box(-lim, lim, dtype=f32))
        self.observation_space.spaces["wrench"] = spaces.Box(-np.inf, np.inf, (6,), dtype=f32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(t.action_dim,), dtype=f32)
        self._zeros = np.zeros(t.action_dim)
        self._oriented = t.oriented
        self._renderer: mujoco.Renderer | None = None
        self._viewer: Any = None
        self._build()
        self._reset_sim()

    # ------------------------------------------------------------------ model
    def _build(self) -> None:
        self.model = build_model(max(640, self.width), max(480, self.height))
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "cup")
        self._hand = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "panda0_link7")
        self._jac = np.zeros((6, m.nv))  # the cup is on link7: the finger columns stay 0
        self._jacp, self._jacr = self._jac[:3], self._jac[3:]
        # Views into MjData, valid as long as it lives: each attribute access on MjData builds a
        # new array object, which the per-step code would otherwise pay for over and over.
        d = self.data
        self._qpos, self._qvel = d.qpos[:N_ARM], d.qvel[:N_ARM]
        self._qpos_all, self._qvel_all, self._ctrl = d.qpos, d.qvel, d.ctrl[:N_ARM]
        self._site_xpos = d.site_xpos[self._site]
        self._site_xmat = d.site_xmat[self._site].reshape(3, 3)
        self._hand_xipos, self._hand_xfrc = d.xipos[self._hand], d.xfrc_applied[self._hand]
        self._warning_stats = tuple(d.warning[w] for w in _INSTABILITY)  # live, like the views
        self._q_home = model_q(self.task.home_q)
        self._q_home_list = self._q_home.tolist()
        kp, kr = self.stiffness, self.rot_stiffness
        # The rotation error below is 2 sin(angle/2)·axis-ish (twice the small-angle form).
        self._k = (kp, 0.5 * kr)
        # About critical damping for ~2 kg at the hand and ~0.05 kg m² about it.
        self._d = (2.0 * math.sqrt(kp * 2.0), 2.0 * math.sqrt(kr * 0.05))
        self._n_sub = round(CONTROL_DT / m.opt.timestep)
        self._build_control()
        # The counterfactual's copies of the simulation (when the push began; the pushed one).
        self._cf_data, self._cf_pushed = mujoco.MjData(m), mujoco.MjData(m)
        geom = functools.partial(mujoco.mj_name2id, m, mujoco.mjtObj.mjOBJ_GEOM)
        self._cup_geom = geom("cup")
        self._object_geoms = frozenset(geom(n) for n in ("pitcher", "plate", "riser", "table"))
        self._load_kernels()

    def _reset_sim(self) -> None:
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:N_ARM] = self._q_home
        d.qpos[N_ARM : N_ARM + 2] = FINGER_OPEN
        d.ctrl[N_ARM:] = FINGER_OPEN
        mujoco.mj_forward(m, d)
        self._home_R = d.site_xmat[self._site].reshape(3, 3).copy()
        self._x = self._read_state()
        self._sp = self._x.copy()
        self._sp_R = self._home_R.copy()
        self._time = 0.0
        self._warnings = 0
        self._wrench = np.zeros(6)
        self._held = HeldWrench()
        self._scripted: ScriptedWrench | None = None
        self._active = False
        self._segment = PushSegmenter.for_hold_off(self.force_threshold, self.hold_off, CONTROL_DT)
        self._held_sp: tuple[np.ndarray, np.ndarray] | None = None
        """The setpoint (pose, rotation) held when the correction began (the arm yields)."""
        self._resume = False
        """A yielded correction just ended: the next step replans from where the cup is."""
        self._corr_start_x = self._x.copy()
        self._corr_t0 = 0.0
        self._trace: list[tuple[float, np.ndarray]] = []
        self._corr_time = 0.0
        self._n_corr = 0
        self._unstable = False
        self._x0 = self._x.copy()
        self._set_plan(np.array([self._x, self._x]), leg="plan")
        self._reset_control()
        self._braked = False
        self._brake_q = self._qpos.copy()
        self._release_at = math.inf
        self._reflex = False
        self._n_reflex = 0
        self._pause_until = -1.0
        self._rest_x = self._x.copy()
        self._cf_steps = 0
        self._cf_done = 0
        """Steps of the push the copy ``_cf_data`` has been run on (``_counterfactual``)."""
        self._cf_control: dict[str, Any] = {}
        self._rerun = False
        self._touched = False
        self._n_contact = 0

    def _read_state(self) -> np.ndarray:
        if not self._oriented:
            return self._site_xpos.copy()
        return np.concatenate([self._site_xpos, mat_to_rpy(self._site_xmat)])

    # ------------------------------------------------------------------ wrenches
    def apply_wrench(
        self, force: Any, torque: Any = (0.0, 0.0, 0.0), duration: float = 1.0
    ) -> None:
        """Push the hand (at the cup) with ``force`` (N) and ``torque`` (N m), world frame, for
        ``duration`` seconds from the next step on (replaces an unfinished scripted push)."""
        f = vector_arg("force", force, 3)
        tq = vector_arg("torque", torque, 3)
        duration = _positive("duration", duration)
        self._scripted = ScriptedWrench(
            np.concatenate([f, tq]), max(1, round(duration / CONTROL_DT))
        )

    def hold_wrench(self, force: Any, torque: Any = (0.0, 0.0, 0.0)) -> None:
        """Apply ``force``/``torque`` on the hand every step until called again (zeros stop it):
        for an interactive front end that reads a person's push (e.g. the viewer's
        perturbation after ``sync()``) and hands it to the env."""
        self._held.wrench6 = np.concatenate(
            [vector_arg("force", force, 3), vector_arg("torque", torque, 3)]
        )

    def _external_wrench(self) -> np.ndarray:
        """The sum of every pusher's wrench this step (``people.Pusher``: the held one, a
        script's, the simulated person's), in that order."""
        t, x = self._time, self._x
        w = np.concatenate(self._held.wrench(t, x, None))
        if self._scripted is not None:
            f, tq = self._scripted.wrench(t, x, None)
            w[:3] += f
            w[3:] += tq
            if self._scripted.done:
                self._scripted = None
        person = self.person
        if person is not None:
            # A participant who only sees the cup is handed no θ̂.
            seen = self.theta_hat if person.needs_theta_hat else None
            f, tq = person.wrench(self._time, self._x, seen)
            w[:3] += f
            w[3:] += tq
        if self.version.reflex:
            self._reflex_decides(w)
        return w

    def _reflex_decides(self, w: np.ndarray) -> None:
        """The reflex's decision on the summed wrench (before the physics runs)."""
        fx, fy, fz, tx, ty, tz = w.tolist()
        force, torque = math.hypot(fx, fy, fz), math.hypot(tx, ty, tz)
        if force > self.reflex_force or torque > self.reflex_torque or self._overloads(w):
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

    def _overloads(self, w: np.ndarray) -> bool:
        """With the version's ``torque_reflex``: whether the wrench loads a joint beyond that
        share of its motor's torque (Jᵀ w at the last physics chunk's Jacobian): the motor
        cannot hold it, so the push would turn the arm about that joint, not move the cup as
        pushed; the Panda's own controller stops on such external joint torques."""
        share = self.version.torque_reflex
        if not share or not w.any():
            return False
        load = self._jac[:, :N_ARM].T.dot(w).tolist()
        return any(abs(t) > share * lim for t, lim in zip(load, self._tlim, strict=True))

    def pause(self, seconds: float) -> None:
        """Hold the setpoint where it is for ``seconds`` (the robot waits, then goes on)."""
        self._pause_until = self._time + _positive("seconds", seconds) - 1e-9

    # ------------------------------------------------------------------ plan and setpoint
    def _set_plan(self, waypoints: np.ndarray, leg: str) -> None:
        """Plans for θ̂ are clipped to ``reach`` where set (``within_reach``); the way home is
        reachable as it is."""
        if leg == "plan" and self.reach is not None:
            waypoints = within_reach(self.task, waypoints, *self.reach)
        plan = np.asarray(waypoints, dtype=np.float64)
        self.plan_waypoints = plan  # what the robot follows now (a viewer draws it)
        # The segments' displacements (angles wrapped) once per plan, not twice per step.
        self._segments = angle_delta(plan[1:], plan[:-1])
        self._leg = leg
        self._tau = 0.0
        self._plan_theta = self.theta_hat.tolist()

    def _replan(self) -> None:
        """Plan for θ̂ from the cup's pose; the setpoint restarts there (it stays where a person
        left it)."""
        self._set_plan(self.task.plan(self.theta_hat, self._x)[0], leg="plan")
        self._sp = self._x.copy()
        self._adm = REST  # the admittance's displacement is now the setpoint's
        if self._oriented:
            self._sp_R = rpy_to_mat(self._sp[3:])
        else:  # upright (a yielded correction may have left it tilted)
            self._sp_R = self._home_R

    def _plan_step(self, k0: float, k1: float) -> np.ndarray:
        """The plan's displacement from k0 to k1 waypoints along it (0 < k1 − k0 < 1): the
        covered parts of at most two segments; it stands still past its last waypoint."""
        seg = self._segments
        n, i, j = len(seg), int(k0), int(k1)
        if i >= n:
            return np.zeros(seg.shape[1])
        if j == i:
            return (k1 - k0) * seg[i]
        step = (j - k0) * seg[i]
        return step + (k1 - j) * seg[j] if j < n else step

    def _move_setpoint(self, u_r: np.ndarray) -> tuple[np.ndarray, Velocity]:
        """Move the setpoint one step along the plan plus the residual: (its displacement, its
        velocity in the world frame). Braked or paused: it stays."""
        if self._braked or self._time < self._pause_until:
            return self._zeros, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        end = len(self._segments) * SEGMENT_TIME
        if self._leg == "plan" and self._tau >= end + END_HOLD:
            ret = straight(self._sp, self.task.start, self.task.plan_pos_bound)
            if self.version.hull_return:
                # hull_return is set on versions whose Tasks carry the hulls (StudyTaskV2)
                ret = cast("StudyTaskV2", self.task).around_hulls(ret)
            self._set_plan(ret, leg="return")
        elif self._leg == "return" and self._tau >= end:
            self._replan()
        k0 = self._tau / SEGMENT_TIME
        self._tau += CONTROL_DT
        step = self._plan_step(k0, self._tau / SEGMENT_TIME) + u_r
        self._sp = self._sp + step
        # In plain floats where numpy would pay a call per 3-vector (this runs every step).
        dx, dy, dz, *turn = step.tolist()
        rx = ry = rz = 0.0
        if self._oriented:
            r0, self._sp_R = self._sp_R, rpy_to_mat(self._sp[3:])
            if any(turn):
                rx, ry, rz = rotation_error(self._sp_R, r0).tolist()
        dt = CONTROL_DT
        return step, (dx / dt, dy / dt, dz / dt, rx / dt, ry / dt, rz / dt)

    # ------------------------------------------------------------------ reset / step
    def human_maker(self) -> None:
        """None: the study's person pushes (``env.person``), it is no correcting ``Human``."""
        return None

    def _start_episode(self, theta_star: np.ndarray, human_rng: np.random.Generator) -> None:
        """The template's, then this episode's person (``persons.build``) from ``human_rng``."""
        self.person = None
        super()._start_episode(theta_star, human_rng)
        if self.person_spec is not None:
            self.person = persons.build(self.person_spec, self.task, theta_star, human_rng)

    def draw_theta_stars(self, rngs: list[np.random.Generator]) -> np.ndarray:
        """The Task's θ* (the study's participant wants one thing); no draw."""
        return np.tile(self.task.theta_star, (len(rngs), 1))

    def draw_starts(
        self, rngs: list[np.random.Generator], human_rngs: bool = True
    ) -> tuple[np.ndarray, list[np.random.Generator]]:
        """The arm starts at home; θ̂0 ~ U[−1, 1]^d, then the user's generator. One episode at
        a time (the study has no vector env): θ̂0 is the last generator's."""
        users = []
        for rng in rngs:
            self._theta_hat0 = rng.uniform(-1.0, 1.0, size=self.task.dim)
            users.append(np.random.default_rng(int(rng.integers(2**63))))
        return np.tile(self.task.start, (len(rngs), 1)), users

    def start_override(self, x0: np.ndarray) -> np.ndarray:
        raise ValueError("reset option 'state' is not supported: the study starts at home")

    def _place_start(self, x0: np.ndarray) -> np.ndarray:
        self.theta_hat = self._theta_hat0
        self._reset_sim()
        self._replan()
        return self._x

    def _start_info(self) -> dict[str, Any]:
        return {**self._study_info(self._zeros, None), "theta_hat0": self._theta_hat0.copy()}

    def _transition(self, u_res: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, dict]:
        """The person's push decides the step (``segment.PushSegmenter``): a correction lasts
        while the felt wrench exceeds the threshold (and, with a hold-off, until it has stayed
        below it that long), the setpoint held (or yielding, ``_yield``); when it ends, u_H is
        the pose change (v2: against the counterfactual)."""
        self._reflex = False
        if self._unstable:
            raise RuntimeError("the episode ended unstable; call reset()")
        if not self._active and (self._resume or self.theta_hat.tolist() != self._plan_theta):
            self._replan()  # after a yielded correction, from where the person left the cup
        self._resume = False
        self._wrench = self._external_wrench()
        fx, fy, fz, tx, ty, tz = self._wrench.tolist()
        felt = math.hypot(fx, fy, fz) + math.hypot(tx, ty, tz) / TORQUE_LEVER
        event = self._segment.feed(felt, not self._braked)
        u_h, is_correction, record = self._zeros, False, None
        if event == "start":
            self._active, self._corr_t0 = True, self._time
            self._corr_start_x = self._correction_start()
            self._trace = []
            self._held_sp = (self._sp, self._sp_R)
            if self.version.counterfactual:
                mujoco.mj_copyData(self._cf_data, self.model, self.data)
                self._cf_control, self._cf_steps, self._cf_done = self._control_state(), 0, 0
        elif event == "end":
            if self.version.counterfactual:
                self._corr_start_x = self._counterfactual()
            self._active = False
            is_correction = True
            u_h = angle_delta(self._x, self._corr_start_x)[: self.task.action_dim]
            self._n_corr += 1
            record = self._record(u_h)
        if self.version.hold_off is not None and event in ("release", "end"):
            # The arm yields: let go, it stays where the person left it (the hold-off, the
            # step the correction ends) and the robot replans from there afterwards.
            self._yield(is_correction)
        if self._active or is_correction:
            u_r, v_sp = self._zeros, _STILL
        else:
            u_r, v_sp = self._move_setpoint(u_res)
        pushed = self._segment.phase == "pushing"
        x_before = self._x
        self._touched = False
        self._simulate(v_sp)
        self.steps += 1
        if self._active:  # the speed reflex may have ended it within the step
            self._cf_steps += 1
            self._corr_time += CONTROL_DT if pushed else 0.0
            self._trace.append((self._time, self._wrench.copy()))
        stable = self._check_stable()
        if stable:
            self._x = self._read_state()
        else:
            self._unstable = True
            self._x = x_before
        info = self._study_info(u_h, record)
        if self.version.reflex:
            info.update(
                reflex=self._reflex,
                braked=self._braked,
                reflexes=self._n_reflex,
                lag=math.dist(self._sp[:3].tolist(), self._x[:3].tolist()),
                gave_up=float(getattr(self.person, "gave_up", False)),
            )
        if self.version.contact_info:
            self._n_contact += self._touched
            info.update(contact=self._touched, contacts=self._n_contact)
        if self.version.hold_off is not None:
            phase = "ended" if is_correction else self._segment.phase
            info["correction_phase"] = phase if self._active or is_correction else "idle"
        return u_h, u_r, is_correction, info

    def _counterfactual(self) -> np.ndarray:
        """The pose the held arm reaches without the push: the simulation as it was when the
        push began, run again over the same steps (the whole correction, hold-off included)
        with no external wrench (the setpoint held where it was when the push began, the
        integral frozen, as during the push); then the pushed simulation is put back. The
        rerun's end is kept as the copy (``_cf_done`` steps on): a later release or the end
        continues it instead of running the same steps again (the same bytes: the copy is
        the whole simulation and controller state)."""
        m, d = self.model, self.data
        mujoco.mj_copyData(self._cf_pushed, m, d)
        control, wrench, time = self._control_state(), self._wrench, self._time
        setpoint = self._sp, self._sp_R
        self._sp, self._sp_R = cast("tuple[np.ndarray, np.ndarray]", self._held_sp)
        mujoco.mj_copyData(d, m, self._cf_data)
        self._set_control_state(self._cf_control)
        self._wrench = np.zeros(6)
        touched, self._rerun = self._touched, True
        for _ in range(self._cf_steps - self._cf_done):
            self._simulate(_STILL)
        self._rerun = False
        unpushed = self._read_state()
        mujoco.mj_copyData(self._cf_data, m, d)
        self._cf_control, self._cf_done = self._control_state(), self._cf_steps
        mujoco.mj_copyData(d, m, self._cf_pushed)
        self._set_control_state(control)
        self._wrench, self._time, self._touched = wrench, time, touched
        self._sp, self._sp_R = setpoint
        return unpushed

    def _yield(self, ended: bool) -> None:
        """The setpoint moves with the person's push so far (``_yield_setpoint``): the push's
        displacement from the counterfactual (recomputed at a release; at the end it is
        ``_corr_start_x``), or from the pose where it began without one."""
        held = cast("tuple[np.ndarray, np.ndarray]", self._held_sp)
        unpushed = self._corr_start_x
        if not ended and self.version.counterfactual:
            unpushed = self._counterfactual()
        self._yield_setpoint(held, (self._x, unpushed))
        self._resume = ended

    def _truncated(self) -> bool:
        """After ``duration`` seconds, at an instability, or at ``max_episode_steps``."""
        return self._unstable or super()._truncated() or self._time >= self.duration - 1e-9

    def _trip(self) -> None:
        self._braked, self._reflex = True, True
        self._n_reflex += 1
        self._brake_q = self._qpos.copy()
        self._qvel_all[:] = 0.0
        self._active = False  # the shove is no correction
        self._segment.cancel()
        self._integral = [0.0] * 6

    def _release(self) -> None:
        self._braked = False
        self._release_at = math.inf
        self._replan()

    def _correction_start(self) -> np.ndarray:
        """The pose a correction's u_H is measured from: the cup's pose when it begins; with
        the version's ``rest_pose``, where the held arm would rest: its setpoint, unless the
        cup is more than ``REST_TRUST`` from it (a setpoint beyond reach or behind an obstacle,
        where the arm rests short of it)."""
        if not self.version.rest_pose:
            return self._x.copy()
        if math.dist(self._sp[:3].tolist(), self._x[:3].tolist()) > REST_TRUST:
            return self._x.copy()
        return self._sp.copy()

    def _record(self, u_h: np.ndarray) -> dict[str, Any]:
        times = np.array([t for t, _ in self._trace])
        wr = np.array([w for _, w in self._trace]).reshape(-1, 6)
        return {
            "start_time": self._corr_t0,
            "end_time": self._time,
            "state": self._corr_start_x.copy(),
            "u_h": np.array(u_h),
            "times": times,
            "force": wr[:, :3],
            "torque": wr[:, 3:],
            "theta_hat": self.theta_hat.copy(),
        }

    def _obs(self, u_h: np.ndarray, phi: np.ndarray) -> dict[str, np.ndarray]:
        obs = super()._obs(u_h, phi)
        # Clipped to float32's finite range: an absurd wrench (say 1e39 N) must not observe inf.
        # Checked in plain floats first: np.clip costs more than the rest of the observation.
        w = self._wrench
        if max(map(abs, w.tolist())) > _F32_MAX:
            w = np.clip(w, -_F32_MAX, _F32_MAX)
        obs["wrench"] = w.astype(np.float32)
        return obs

    def _study_info(self, u_h: np.ndarray, record: dict[str, Any] | None) -> dict[str, Any]:
        """The study's own info keys (the shared ones come from the template)."""
        info = {
            "u_h": np.array(u_h, dtype=np.float64),
            "correction_active": self._active,
            "correction_time": self._corr_time,
            "corrections": self._n_corr,
            "time": self._time,
            "wrench": self._wrench.copy(),
            "setpoint": self._sp.copy(),
            "unstable": self._unstable,
        }
        if record is not None:
            info["correction_state"] = record["state"].copy()
            info["correction_record"] = record
        return info

    # ------------------------------------------------------------------ render, close, pickle
    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        # _build remakes the MjData views; MuJoCo's warning records do not pickle.
        for key in ("model", "data", "_renderer", "_viewer", "_warning_stats"):
            state.pop(key, None)
        for key in ("_cf_data", "_cf_pushed", "_object_geoms"):
            state.pop(key, None)
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        sim = np.empty(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self.data, sim, spec)
        state["_sim"] = sim
        cf = np.empty_like(sim)
        mujoco.mj_getState(self.model, self._cf_data, cf, spec)
        state["_cf_sim"] = cf
        return state

    def __setstate__(self, state: dict) -> None:
        sim = state.pop("_sim")
        cf = state.pop("_cf_sim", None)
        self.__dict__.update(state)
        self._renderer = None
        self._viewer = None
        self._build()
        mujoco.mj_setState(self.model, self.data, sim, mujoco.mjtState.mjSTATE_INTEGRATION)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        if cf is not None:  # a push under way: its counterfactual starts from here
            mujoco.mj_setState(self.model, self._cf_data, cf, mujoco.mjtState.mjSTATE_INTEGRATION)
            mujoco.mj_forward(self.model, self._cf_data)


REFLEX_FORCE_RANGE = (20.0, 150.0)
"""``reflex_force`` (N) accepted: above the 15 N threshold (a push must be able to correct) and
at most 150 N, where v2's joint brakes still hold every joint under its speed limit for any
push below the reflex (docs/study.md)."""
REFLEX_TORQUE_RANGE = (2.0, 15.0)
"""``reflex_torque`` (N m) accepted: at least the 15 N threshold's torque at the 0.1 m lever
(1.5 N m, rounded up) and at most 15 N m (docs/study.md)."""


def _within(name: str, value: Any, bounds: tuple[float, float]) -> float:
    """A finite number in [low, high], else a ValueError naming ``name`` and the range."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    low, high = bounds
    if not (math.isfinite(v) and low <= v <= high):
        raise ValueError(f"{name} must be a finite number in [{low:g}, {high:g}], got {value!r}")
    return v


def _positive(name: str, value: Any) -> float:
    return float(checks.number(name, value, low=0, low_open=True, text=True))


class StudyEnvV1(StudyEnv):
    """StROL-Study-v1: the study env with version ``V1``: u_H = the person's
    push, the Panda's joint limits and a Cartesian force reflex (``versions.V1``,
    ``docs/study.md``). It only names its version: the env is ``StudyEnv``.

    Its people (``person``): "observer" (default; σ, ε and ``ParticipantParams``, no human
    model, no β) or "oracle" (v0's user; a human model's name picks its model). Extra
    arguments: ``reflex_force`` (N, > 0, default 100), ``reflex_torque`` (N m, > 0, default 10),
    ``reflex_recover`` (s, > 0, default 0.5).
    Extra ``info``: ``reflex`` (the reflex tripped this step), ``braked``, ``reflexes`` (count
    this episode), ``lag`` (the cup's distance to its setpoint, m), ``gave_up`` (1.0 once the
    participant has given up, else 0.0). ``pause(seconds)`` holds
    the setpoint where it is.

    ## Version History

    - v1: u_H measured against the held setpoint, integral and damping feedforward in the
      impedance law, joint speed and torque limits, the force reflex, ``pause``.
    - v0: initial version (kept, deprecated, for the published results).
    """

    version: ClassVar[StudyVersion] = V1


class StudyEnvV2(StudyEnv):
    """StROL-Study-v2: the study env with version ``V2`` (``versions.V2``, ``docs/study.md``).

    What v1 got wrong, measured on pushes no test tuned on, and what v2 does instead:

    - **u_H is the displacement the person caused, on any push.** When a push begins the
      simulation is copied (``mj_copyData``); when it ends the copy is run over the same
      steps with the setpoint held and no external wrench (what the held arm would have done),
      and u_H = the pushed pose − that unpushed pose, whatever the arm's lag.
      ``info["correction_state"]`` = the unpushed pose x, the pose u_H is added to. u_H's
      position part is the difference of the cup's positions (m, world frame); its rotation
      part (Tasks 2-3) is the difference of the Euler angles (roll, pitch, yaw: the Task's
      convention R = Rz Ry Rx, wrapped to [−π, π)), so x + u_H is the pushed pose; the
      world-frame rotation R(x + u_H) R(x)⁻¹ is the turn the push produced, about the torque's
      axis for a pure torque. A wrench acts at the cup frame's origin (the cup's centre, the
      state's position).
    - **The push moves the cup as pushed (an admittance layer):** the person's wrench (known:
      the push API applies it; a real Panda reads it from its joint torque sensors) drives an
      isotropic virtual mass-spring-damper per axis (``admittance``: ``stiffness`` N/m and
      ``rot_stiffness`` N m/rad, 6 rad/s, critically damped), and the arm tracks its setpoint
      displaced by it (position + δ_p, orientation exp(δ_r) R) with the wrench cancelled in
      the torques: a force moves the cup along it, a torque turns it about its axis, whatever
      the arm's inertia. The tracking law's gains are a bandwidth, K = ω²Λ and D = 2ωΛ
      (ω = 14 rad/s, Λ the cup's task-space inertia), with a bounded integral frozen while a
      push lasts. During a correction the arm yields (its target follows the push); the
      setpoint itself is held, and the plan restarts from where the person left the cup.
    - **The arm reaches where it is sent:** the Task (``StudyTask{1,2,3}V2``) plans within
      the reachable set (``ReachSet``: a box, a shell around the shoulder, a roll and pitch
      bound, derived from the arm model by ``lab/study/study_reach.py``, named in
      ``reach_source``) and out of the objects' hulls, which it carries as data; the robot
      executes its plans as they are (no clipping: ``reach`` is None), and the regret uses the
      same planner.
    - **The Panda's limits at every physics step**, through the torques (``joint_brake``:
      from 0.9x a joint's speed limit its torque saturates against the motion); a push that
      spins a joint towards its limit trips a speed reflex (the brakes lock,
      ``info["reflex"]``) before the joint passes it, and one that loads a joint beyond 0.9 of
      its motor's torque limit (Jᵀw) trips the reflex at once (``torque_reflex``): the motor
      could not also hold the arm, so it would turn about that joint, not move as pushed. The
      position limits too (``joint_room``): the null space keeps the twisting joints (1, 3,
      5, 7) off theirs, and a push that drives one of them to its limit trips the reflex.
      ``reflex_force`` in [20, 150] N and ``reflex_torque`` in [2, 15] N m, else ValueError.
    - **Softer**: ``stiffness`` 300 N/m and ``rot_stiffness`` 10 N m/rad by default (v1: 400
      and 30), the admittance's: a 30 N push for 1 s moves the cup 9.8 cm (the paper's
      participants: a median 11 cm per correction).
    - ``info["contact"]``: the cup touched the pitcher, the plate or the table this step
      (``info["contacts"]`` counts the steps).
    - **One push, one correction.** A correction ends only once the felt force has stayed at
      or below ``force_threshold`` for ``hold_off`` seconds (default 0.4, in [0, 0.5];
      ``segment.PushSegmenter``): a push that eases off and comes back within it is the same
      correction. Released, the arm yields: its setpoint is the held one moved by the push
      so far, so it stays where the person left it through the hold-off, and afterwards the
      robot replans from there. u_H's counterfactual covers the whole correction, hold-off
      included; ``correction_time`` counts the seconds above the threshold.
      ``info["correction_phase"]``: "idle", "pushing", "holding" (the hold-off) or "ended".

    The person is one of the population fitted to the authors' twelve participants
    (``person="fitted"``, default; ``population``, ``participant.FittedParticipant``; its
    ``kwargs`` override the drawn fields; it takes no σ, ε or β: its noise is fitted), or v1's
    ``"observer"`` and ``"oracle"``; the ĝ are v2's own (trained on the fitted population's
    corrections).

    ## Version History

    - v2: u_H by counterfactual, an admittance layer, the Task's reachable set and hulls,
      joint limits at every physics step, a softer arm, ``info["contact"]``, one push one
      correction (the hold-off, the arm yielding).
    - v1: u_H measured against the held setpoint (deprecated).
    - v0: initial version (deprecated).
    """

    version: ClassVar[StudyVersion] = V2


__all__ = ["PARTICIPANTS", "StudyEnv", "StudyEnvV1", "StudyEnvV2", "rotation_error"]
