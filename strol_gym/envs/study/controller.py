"""The study's impedance controllers, one per version's option ``controller``.

- ``"v0"``: τ = Jᵀ(K e − D (J q̇ − v_sp)) + a weak pull to the home joints, with scalar gains
  (StROL-Study-v0, as published).
- ``"v1"``: adds a bounded integral (frozen while a person pushes), damping critical for the
  arm's task-space inertia Λ, Λ a_sp and the joints' damping fed forward, the home pull in the
  null space only, and the Panda's joint speed limits (StROL-Study-v1).

A mixin of ``StudyEnv`` (``strol_gym.envs.study.env``): it reads the env's MuJoCo views and
setpoint; the env calls ``_simulate`` once per control step.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar

import mujoco
import numpy as np

from strol_gym.compiled import use_fast
from strol_gym.envs.panda.model import N_ARM
from strol_gym.envs.study.admittance import REST, Admittance, rotation
from strol_gym.envs.study.scene import HOLD, JOINT_DAMPING
from strol_gym.tasks.study import CONTROL_DT, mat_to_rpy, rpy_to_mat

_INSTABILITY = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
)
Velocity = tuple[float, float, float, float, float, float]
"""The setpoint's linear (m/s) and angular (rad/s) velocity, world frame."""
K_NULL, D_NULL = 0.5, 0.5
"""A weak joint-space pull towards the home joints (N m/rad, N m s/rad): keeps the redundant
elbow from drifting; a few N/m at the hand, small next to the Cartesian stiffness."""
VELOCITY_LIMIT = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
"""The Panda's joint speed limits (rad/s, datasheet)."""
TORQUE_LIMIT = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])
"""The Panda's joint torque limits (N m, datasheet)."""
LIMIT_BAND = 0.5
"""v2 (``joint_room``): rad from a position limit within which the null space's posture
spring also pulls a twisting joint (1, 3, 5, 7: ``LIMIT_JOINTS``) back to the band's edge, with
``K_LIMIT``. The arm's spare degree of freedom is all it uses, so the cup's pose is untouched:
at a corner of Tasks 2-3's reachable set (the cup rolled and pitched near the base) joint 7
sat 0.02-0.04 rad past its limit, the cup 3 cm short of its setpoint, and a twist there turned
it about another axis (up to 137° off; 200 held-out pushes per Task, ``--seed 33``)."""
K_LIMIT = 20.0
"""N m/rad of the posture spring's pull off a limit (``LIMIT_BAND``); 40 and a 0.3 rad band
read alike on the held-out pushes."""
LIMIT_JOINTS = (True, False, True, False, True, False, True)
"""The joints the null space can turn without moving the cup much; the others' limits
(the elbow stretched, the shoulder and wrist bent) are the cup's position, which the spring
could only fight: with them in the band, 10 more pushes per 200 read off their direction."""
POSITION_REFLEX = 0.02
"""v2 (``joint_room``): rad from its position limit at which a twisting joint (``LIMIT_JOINTS``)
that a person's push drives towards it trips the reflex (the Panda stops on its joint position
limits): there the arm turns about the stopped joint, not as pushed. Not the elbow: this
model stops it straightening at −0.4 rad (the Panda's datasheet: −0.07), and the fitted people
pushed it there in 157 of about 600 pushes (12 users' sessions), which a reflex would all lose;
a push that stretches the arm to its end meets it, as a wall, and reads off its direction
(up to 166°, 1-2 in 200 held-out pushes)."""
K_INTEGRAL = (10.0, 10.0)
"""Integral gains of the impedance law, as multiples of the stiffness (1/s): position, rotation."""
INTEGRAL_MAX = (8.0, 0.8)
"""Bounds of the integral wrench per axis (N, N m): it can cancel a few newtons of unmodelled
force (joint friction, the elbow's pull), never fight a person."""
JOINT_COMP = 1.0
"""v2, while a wrench pushes: the joints' viscous damping (``JOINT_DAMPING``) cancelled at each
physics step (its share of q̇), so that the push meets the Cartesian impedance only: with it,
the joints' damping turned a 30 N push along x 17° towards −z within 1 s (Task 1, seed 1) and
left the cup 28 % short of F/K (cancelled: 11° and 20 %)."""
WATCH_FROM = 0.25
"""v2 steps one physics step at a time (braking if need be) while a wrench pushes or any joint
is above 0.25x its speed limit (the arm springing back after a push)."""
SPEED_REFLEX = 1.0
"""v2's speed reflex (the brakes lock the arm, ``info["reflex"]``): while a person pushes, when
a joint would pass its speed limit at the next physics step under the torques about to act
(``_too_fast``: the push drives the arm faster than it may go); at any time, when a joint
would pass it even with its motor's full torque against the motion (its speed plus the last
step's acceleration): a load beyond its motor cannot be braked by the torques. The arm's own
torques never trip it: the brake holds them (before, a reflex read the speed alone and the
arm's own motion tripped it on some seeds with nobody pushing)."""
BRAKE_FROM = 0.9
"""v2's joint brake: a joint whose speed at the next physics step (``_ahead``: the speed plus
the acceleration under the torque about to act) would pass 0.9x its limit gets the torque that
holds it at 0.9x, within its motor's range (saturation: the motors' torque is all there is;
``qvel`` is never written). A brake reading the present speed alone let a 7-8 N m twist, or
the wrist springing back after one, pass the limit by up to 1.75x within a physics step."""
EXACT_FROM = 0.7
"""v2's joint brake reads the acceleration at the present state (one extra acceleration stage
per physics step) once a joint's speed, or its next step's by the cheap look-ahead, passes
0.7x its limit; below that it reads the last step's."""
ADMITTANCE_SPEED = 0.5
"""v2: the share of each joint's speed limit the admittance's motion may ask of it
(``_cap_speed``); the plan's motion and the tracking come on top."""
_CONTROL_STATE = (
    "_integral",
    "_v_prev",
    "_model_age",
    "_v_feed",
    "_acc_ff",
    "_const",
    "_gain",
    "_pull_home",
    "_lam",
    "_dyn_inv",
    "_jt_damp",
    "_adm",
    "_kmat",
    "_m_inv",
    "_tau_last",
)
"""v1's controller state between steps (each rebound, never changed in place)."""
MODEL_EVERY = 4
"""Control steps between refreshes of Λ, D and the null-space projector (0.2 s)."""
_ZERO6 = [0.0] * 6
_ZERO7 = [0.0] * 7
_ZERO13 = [0.0] * 13
_TWISTS = np.array(LIMIT_JOINTS)
_STAGE_VEL = int(mujoco.mjtStage.mjSTAGE_VEL)
_kernels: Any = None
"""(``chunk``, ``step_kernel``) once a controller found the compiled chunk's C functions
(those modules import numba: imported only then)."""
_loaded = False
"""Whether a controller loaded the compiled step's kernels (``_load_kernels``: once a process)."""
LAMBDA_REG = 1e-2 * np.eye(6)
"""Added to J M⁻¹ Jᵀ before inverting it: near a singular pose Λ stays ≤ ~100 kg."""


class ImpedanceController:
    """The controllers of the study env (see the module docstring)."""

    if TYPE_CHECKING:  # the env's views and state this mixin reads (StudyEnv sets them)
        model: Any
        data: Any
        version: ClassVar[Any]
        _k: tuple[float, float]
        _d: tuple[float, float]
        _qpos: np.ndarray
        _qvel: np.ndarray
        _qpos_all: np.ndarray
        _qvel_all: np.ndarray
        _ctrl: np.ndarray
        _jac: np.ndarray
        _jacp: np.ndarray
        _jacr: np.ndarray
        _site: int
        _site_xpos: np.ndarray
        _site_xmat: np.ndarray
        _hand_xipos: np.ndarray
        _hand_xfrc: np.ndarray
        _q_home: np.ndarray
        _q_home_list: list[float]
        _warnings: int
        _n_sub: int
        _warning_stats: tuple[Any, ...]
        _sp: np.ndarray
        _sp_R: np.ndarray
        _x: np.ndarray
        _oriented: bool
        _time: float
        _wrench: np.ndarray
        _active: bool
        _braked: bool
        _brake_q: np.ndarray
        _rerun: bool
        _cup_geom: int
        _object_geoms: frozenset[int]
        _touched: bool
        stiffness: float
        rot_stiffness: float

        def _trip(self) -> None: ...

    def _build_control(self) -> None:
        """The controllers' fixed terms, once the model and its views exist."""
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
        self._brake_vlim = (BRAKE_FROM * VELOCITY_LIMIT).tolist()
        self._exact_vlim = (EXACT_FROM * VELOCITY_LIMIT).tolist()
        self._watch_vlim = (WATCH_FROM * VELOCITY_LIMIT).tolist()
        self._watch_cap, self._brake_cap = WATCH_FROM * VELOCITY_LIMIT, BRAKE_FROM * VELOCITY_LIMIT
        self._reflex_vlim = (SPEED_REFLEX * VELOCITY_LIMIT).tolist()
        self._qacc = self.data.qacc[:N_ARM]
        self._tlim = TORQUE_LIMIT.tolist()
        self._integral_max = self.version.integral_max or INTEGRAL_MAX
        self._cap_vlim = (ADMITTANCE_SPEED * VELOCITY_LIMIT).tolist()
        self._jnt_range = self.model.jnt_range[:N_ARM].T.copy()
        self._jnt_low, self._jnt_high = (r.tolist() for r in self._jnt_range)
        if self.version.admittance:
            dt = HOLD * self.model.opt.timestep
            self._admit = Admittance(self.stiffness, self.rot_stiffness, dt)
        self._fp: np.ndarray | None = None  # the compiled chunk's C addresses, once looked up
        self._dt = float(self.model.opt.timestep)  # MjModel.opt builds a wrapper per access
        self._caps = np.array(
            [
                BRAKE_FROM * VELOCITY_LIMIT,
                EXACT_FROM * VELOCITY_LIMIT,
                SPEED_REFLEX * VELOCITY_LIMIT,
                TORQUE_LIMIT,
                [JOINT_COMP * c for c in JOINT_DAMPING.tolist()],
                *self._jnt_range,
                _TWISTS,
                WATCH_FROM * VELOCITY_LIMIT,
            ]
        )  # ``step_kernel``'s rows

    def _control_state(self) -> dict[str, Any]:
        """The controller's state (v1's), to run the simulation again from here."""
        return {k: getattr(self, k) for k in _CONTROL_STATE if hasattr(self, k)}

    def _set_control_state(self, state: dict[str, Any]) -> None:
        for k, v in state.items():
            setattr(self, k, v)

    def _reset_control(self) -> None:
        """v1's controller state at a reset (v0 keeps none)."""
        self._integral = [0.0] * 6
        self._v_prev = _ZERO6
        self._model_age = 0
        self._v_feed: list[float] | None = None
        self._adm = REST
        self._tau_last = [0.0] * N_ARM

    def _yield_setpoint(
        self, held: tuple[np.ndarray, np.ndarray], moved: tuple[np.ndarray, np.ndarray]
    ) -> None:
        """The arm yields to a person who let go: its setpoint is the held one (``held``: pose,
        rotation) moved as the person moved the cup (``moved``: the pushed pose, then the
        pose the held arm reaches without the push), so the arm neither springs back nor stops
        its own motion where the push left it. Without orientation in the state (Task 1) the
        rotation setpoint is the cup's rotation: released, a tilted cup righting itself would
        drag the cup's position with it. The integral stays frozen (the correction is still
        active). Called before a control step (``versions.StudyVersion.hold_off``)."""
        pushed, unpushed = moved
        # v2's admittance displacement is now the setpoint's (else the target would count the
        # push twice); its spring-back would undo the yield
        self._adm = REST
        pos = held[0][:3] + (pushed[:3] - unpushed[:3])
        if not self._oriented:
            self._sp, self._sp_R = pos, self._site_xmat.copy()
            return
        turn = rpy_to_mat(pushed[3:]).dot(rpy_to_mat(unpushed[3:]).T)
        self._sp_R = turn.dot(held[1])
        self._sp = np.concatenate([pos, mat_to_rpy(self._sp_R)])

    def _simulate(self, v_sp: Velocity) -> None:
        """One control step of physics with the version's controller."""
        if self.version.controller == "v1":
            self._simulate_v1(v_sp)
        else:
            self._simulate_v0(v_sp)

    def _push_at_cup(self) -> None:
        """Hold the person's wrench on the hand: it acts at the cup, so add its lever's torque."""
        fx, fy, fz, tx, ty, tz = self._wrench.tolist()
        if fx or fy or fz or tx or ty or tz:
            lx, ly, lz = (self._site_xpos - self._hand_xipos).tolist()
            self._hand_xfrc[:] = (
                fx,
                fy,
                fz,
                tx + (ly * fz - lz * fy),
                ty + (lz * fx - lx * fz),
                tz + (lx * fy - ly * fx),
            )
        else:
            self._hand_xfrc[:] = 0.0

    def _simulate_v0(self, v_sp: Velocity) -> None:
        """One control step of physics; the impedance torque is recomputed every ``HOLD`` steps.

        τ = Jᵀ(K e − D (J q̇ − v_sp)) + a weak pull to the home joints; e = setpoint − pose
        (orientation error as the rotation vector's small-angle form). v_sp, the setpoint's
        velocity, is a feedforward term so that the arm does not lag its plan.
        """
        m, d = self.model, self.data
        self._push_at_cup()
        jac, jp, jr, ctrl, site = self._jac, self._jacp, self._jacr, self._ctrl, self._site
        q, qd, qd_all, q_home = self._qpos, self._qvel, self._qvel_all, self._q_home_list
        xpos, xmat_t, sp_r = self._site_xpos, self._site_xmat.T, self._sp_R
        (spx, spy, spz), (kp, kr), (dp, dr) = self._sp[:3].tolist(), self._k, self._d
        vx, vy, vz, wx, wy, wz = v_sp
        for _ in range(self._n_sub // HOLD):
            mujoco.mj_jacSite(m, d, jp, jr, site)
            # Plain floats where numpy would pay a call per few numbers, and ndarray.dot (half
            # the cost of @ on arrays this small). The wrench w = K e + D (v_sp − J q̇):
            x, y, z = xpos.tolist()
            (_, r01, r02), (r10, _, r12), (r20, r21, _) = sp_r.dot(xmat_t).tolist()
            jvx, jvy, jvz, jwx, jwy, jwz = jac.dot(qd_all).tolist()  # J q̇
            w = np.array(
                (
                    kp * (spx - x) + dp * (vx - jvx),
                    kp * (spy - y) + dp * (vy - jvy),
                    kp * (spz - z) + dp * (vz - jvz),
                    kr * (r21 - r12) + dr * (wx - jwx),
                    kr * (r02 - r20) + dr * (wy - jwy),
                    kr * (r10 - r01) + dr * (wz - jwz),
                )
            )
            # τ = Jᵀ w + K_NULL (q_home − q) − D_NULL q̇; zip stops at the arm's joints (Jᵀ w
            # also has the fingers', which are 0).
            joints = zip(w.dot(jac).tolist(), q_home, q.tolist(), qd.tolist(), strict=False)
            ctrl[:] = [t + K_NULL * (h - a) - D_NULL * b for t, h, a, b in joints]
            mujoco.mj_step(m, d, HOLD)  # nstep; by keyword, pybind11 costs a third more
        # mj_step leaves positions one physics step old: refresh them (the state read next and
        # the next step's first torque then depend on qpos alone, so a pickled env continues
        # exactly).
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)  # mj_jacSite reads cdof and subtree_com
        self._time += CONTROL_DT

    def _check_stable(self) -> bool:
        """False after a MuJoCo instability warning (it then resets the data) or NaN."""
        qacc, qpos, qvel = self._warning_stats
        warnings = qacc.number + qpos.number + qvel.number
        bad = warnings > self._warnings or not all(map(math.isfinite, self._qpos_all.tolist()))
        self._warnings = warnings
        return not bad

    def _model_terms(self, v_sp: np.ndarray, defer: bool = False) -> tuple[bool, bool, list]:
        """The model-based terms of the control law, at the current pose: the cup's
        task-space inertia Λ, the damping D = √K Λ^½ + Λ^½ √K (critical for the arm's real
        inertia, which v0's scalar gains underestimate 2-5x) and the null-space projector N,
        folded into joint-space matrices (refreshed every ``MODEL_EVERY`` control steps: the
        pose changes little in between); and, when the setpoint's velocity changes, its
        acceleration feedforward Λ a_sp and the torques that move along it (Jᵀ D v_sp and the
        joints' viscous damping at J̄ v_sp, J̄ = M⁻¹ Jᵀ Λ). ``defer``: the compiled path's
        feedforward is the caller's (``_step_compiled``): returns whether Λ a_sp and the
        constant torques are due, and v_sp as a list."""
        refresh = self._model_age <= 0
        if refresh:
            self._model_age = MODEL_EVERY
            if not self._refresh_compiled():
                self._refresh_terms()
        self._model_age -= 1
        v_list = v_sp.tolist()
        fp = self._fp if self._fp is not None and use_fast() else None
        if fp is not None and self.version.track_bandwidth:  # the same sums, compiled
            chunk = _kernels[0]
            acc, feed = v_list != self._v_prev, refresh or v_list != self._v_feed
            if defer:
                return acc, feed, v_list
            if acc or feed:
                v_prev = np.array(self._v_prev)
                acc_ff, const = chunk.feeds(
                    fp, self._lam, self._jt_damp, self._dyn_inv, self._pull_home,
                    JOINT_DAMPING, v_sp, v_prev, 1.0 / CONTROL_DT, acc, feed,
                )  # fmt: skip
            self._acc_ff = acc_ff.tolist() if acc else _ZERO6
            if acc:
                self._v_prev = v_list
            if feed:
                self._v_feed, self._const = v_list, const.tolist()
            return False, False, v_list
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
        return False, False, v_list

    def _refresh_terms(self) -> None:
        """``_model_terms``' refresh: M, Λ, the gains and the null-space pull at this pose."""
        ja = self._jac[:, :N_ARM]
        mujoco.mj_fullM(self.model, self.data, self._mass)
        m_inv_jt = np.linalg.solve(self._mass[:N_ARM, :N_ARM], ja.T)
        lam = np.linalg.inv(ja.dot(m_inv_jt) + LAMBDA_REG)
        band = self.version.track_bandwidth
        if band:  # v2: K = ω² Λ, D = 2ωΛ: each direction tracks with bandwidth ω
            self._kmat = (band * band) * lam
            jt_damp = ja.T.dot((2.0 * band) * lam)
        else:
            vals, vecs = np.linalg.eigh(lam)
            root = (vecs * np.sqrt(np.maximum(vals, 0.0))).dot(vecs.T)
            jt_damp = ja.T.dot(root * self._sqrt_k + self._sqrt_k[:, None] * root)
        # The elbow's pull acts in the task's null space only (N = I − Jᵀ J̄ᵀ): v0's pull,
        # unprojected, turned the wrist off its setpoint by up to 0.05 rad.
        null = self._eye7 - ja.T.dot(lam.dot(m_inv_jt.T))
        # τ = Jᵀ(K e + ∫ + Λ a_sp) + c − G [q; q̇]: G = [K_n N, Jᵀ D J + D_n N].
        stiff: np.ndarray | float
        if self.version.joint_room:  # the pull home plus the pull off the limits
            stiff, pull = self._posture()
            self._pull_home = null.dot(pull)
        else:
            stiff = K_NULL
            self._pull_home = (K_NULL * null).dot(self._q_home)
        self._gain = np.hstack([null * stiff, jt_damp.dot(ja) + D_NULL * null])
        self._lam, self._dyn_inv, self._jt_damp = lam, m_inv_jt.dot(lam), jt_damp
        if self.version.joint_brake:
            self._m_inv = np.linalg.inv(self._mass[:N_ARM, :N_ARM])

    def _refresh_compiled(self) -> bool:
        """``_refresh_terms`` in one compiled call (``chunk.refresh``: v2's branch, numpy's
        own LAPACK and BLAS calls), where it applies; False: the plain path is to run."""
        v = self.version
        if not (v.track_bandwidth and v.joint_room and v.joint_brake):
            return False
        fp = self._chunk_functions()
        if fp is None:
            return False
        ok, *terms = _kernels[0].refresh(
            fp, self._mass, self._jac, self._qpos, self._q_home, self._jnt_range, _TWISTS,
            LAMBDA_REG, v.track_bandwidth, K_NULL, D_NULL, K_LIMIT, LIMIT_BAND,
        )  # fmt: skip
        if not ok:  # singular: the plain path raises numpy's error
            return False
        self._kmat, self._lam, self._jt_damp, self._dyn_inv, self._gain = terms[:5]
        self._pull_home, self._m_inv = terms[5:]
        return True

    def _simulate_v1(self, v_sp: Velocity) -> None:
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
            self._adm = REST
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            self._time += CONTROL_DT
            return
        self._push_at_cup()
        v = self.version
        fp = self._chunk_functions() if v.track_bandwidth and v.joint_brake else None
        # the whole step compiled (a setpoint rotation not C-ordered: the plain path, same bytes)
        if fp is not None and self._sp_R.flags.c_contiguous:
            self._step_compiled(fp, v_sp)
            self._time += CONTROL_DT
            return
        jac, jp, jr, ctrl, site = self._jac, self._jacp, self._jacr, self._ctrl, self._site
        q, qd = self._qpos, self._qvel
        xpos, xmat_t, sp_r = self._site_xpos, self._site_xmat.T, self._sp_R
        (spx, spy, spz), kp, kr = self._sp[:3].tolist(), self._k[0], 2.0 * self._k[1]
        vx, vy, vz, wx, wy, wz = v_sp
        integrate = not self._active
        dt_i = HOLD * self._dt
        band = self.version.track_bandwidth
        if band:  # v2: the integral of the stiffness wrench K e (K = ω² Λ)
            gp, gr = (g * dt_i for g in self.version.integral_gain or K_INTEGRAL)
        else:
            gp, gr = kp * K_INTEGRAL[0] * dt_i, kr * K_INTEGRAL[1] * dt_i
        ip, ir = self._integral_max
        vlim, half = self._vlim, self._half_vlim
        brake = self.version.joint_brake
        wext = self._wrench.tolist()
        pushed = brake and any(wext)  # the hand's applied wrench is nonzero (_push_at_cup)
        mujoco.mj_jacSite(m, d, jp, jr, site)
        self._model_terms(np.array(v_sp))
        admitted = self._admitted(sp_r, wext, dt_i)
        chunks = admitted or [(0.0, 0.0, 0.0, sp_r, None, None, self._adm)] * (self._n_sub // HOLD)
        for i, (ox, oy, oz, target_r, feed, damp, self._adm) in enumerate(chunks):
            if i:
                mujoco.mj_jacSite(m, d, jp, jr, site)
            x, y, z = xpos.tolist()
            # The setpoint where it is at this chunk's start (it moves linearly over the
            # step): a staircase setpoint would put the cup ¾ of a step ahead of it.
            back = CONTROL_DT - i * dt_i
            (_, r01, r02), (r10, _, r12), (r20, r21, _) = target_r.dot(xmat_t).tolist()
            e = (
                spx + ox - vx * back - x,
                spy + oy - vy * back - y,
                spz + oz - vz * back - z,
                0.5 * (r21 - r12) - wx * back,
                0.5 * (r02 - r20) - wy * back,
                0.5 * (r10 - r01) - wz * back,
            )
            integ = self._integral
            if band:
                ke = self._kmat.dot(e).tolist()
                if integrate:
                    integ = [
                        min(lim, max(-lim, a + g * b))
                        for a, b, g, lim in zip(
                            integ,
                            ke,
                            (gp,) * 3 + (gr,) * 3,
                            (ip,) * 3 + (ir,) * 3,
                            strict=True,
                        )
                    ]
                    self._integral = integ
                # in plain floats: numpy would convert each list (the same sums, in order)
                w = np.array([a + b + c for a, b, c in zip(ke, integ, self._acc_ff, strict=True)])
            elif integrate:
                integ = [
                    min(ip, max(-ip, a + gp * b)) for a, b in zip(integ[:3], e[:3], strict=False)
                ] + [min(ir, max(-ir, a + gr * b)) for a, b in zip(integ[3:], e[3:], strict=False)]
                self._integral = integ
            if not band:
                w = np.array(
                    [
                        k * a + b + c
                        for k, a, b, c in zip(
                            (kp, kp, kp, kr, kr, kr), e, integ, self._acc_ff, strict=False
                        )
                    ]
                )
            if feed is not None:
                w += feed
            rest = self._gain.dot(np.concatenate((q, qd))).tolist()
            joints = zip(w.dot(jac).tolist(), self._const, rest, strict=False)
            tau = [t + c - g for t, c, g in joints]
            if damp is not None:  # added to the torques as ctrl holds them (float64 as these)
                tau = [t + b for t, b in zip(tau, damp, strict=True)]
            ctrl[:] = tau
            if brake:
                self._step_braked(bool(pushed))
                if self._braked:  # the speed reflex tripped: the brakes hold from here
                    break
            elif any(abs(s) > h for s, h in zip(qd.tolist(), half, strict=False)):
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

    def _chunk_functions(self) -> np.ndarray | None:
        """The compiled chunk's C addresses for this model and data (``chunk.chunk``'s
        ``fp``), or None: the plain path (``STROL_GYM_KERNELS=plain``, or no C functions
        that give numpy's bits)."""
        if not use_fast():
            return None
        if self._fp is None:
            global _kernels
            from strol_gym.envs.study import chunk, step_kernel

            found = chunk.functions()
            if found is None:
                return None
            _kernels = chunk, step_kernel
            self._fp = np.array([*found, self.model._address, self.data._address], np.intp)
            self._objects = np.array(sorted(self._object_geoms), dtype=np.int64)
            # the compiled control step's buffers (scratch: nothing is kept in them between
            # steps); the chunks without the admittance differ in ``back`` alone
            n, dt_i = self._n_sub // HOLD, HOLD * self._dt
            self._par, self._ints = np.zeros(chunk.PAR), np.zeros(8, dtype=np.int64)
            self._targets, self._var_still = np.empty((n, 3, 3)), np.zeros((n, step_kernel.VAR))
            self._var_still[:, 3] = [CONTROL_DT - i * dt_i for i in range(n)]
            gains = self.version.integral_gain or K_INTEGRAL
            self._step_head = [g * dt_i for g in gains] + list(self._integral_max) + [self._dt]
            if self.version.admittance:  # ``step_kernel.admitted``'s constants and output
                self._adm_coef = np.array([*self._admit.coefficients(), *self._cap_vlim])
                self._adm_states = np.zeros((n, 13))
        return self._fp

    def _admitted(
        self, sp_r: np.ndarray, wext: list[float], dt_i: float
    ) -> list[tuple[Any, ...]] | None:
        """Each chunk's admittance terms (the target's offset and rotation, its wrench feed and
        damping torques, None where they do not apply) and the admittance's state after it:
        they do not depend on the physics, so a control step computes them up front. None:
        the admittance does not act this step (at rest, nobody pushes)."""
        if not (self.version.admittance and (self._adm is not REST or any(wext))):
            return None
        chunks = []
        for _ in range(self._n_sub // HOLD):
            ox = oy = oz = 0.0
            target_r, feed, damp = sp_r, None, None
            if self._adm is not REST or any(wext):  # it may settle within the step
                # The admittance target over this chunk (its midpoint), its velocity and
                # acceleration fed forward, the person's wrench cancelled (the target moves
                # for it): the tracking law carries the cup along δ.
                s0 = self._adm
                s1 = self._adm = self._cap_speed(self._admit.step(s0, wext))
                ox, oy, oz, rx, ry, rz = (0.5 * (a + b) for a, b in zip(s0, s1[:6], strict=False))
                target_r = rotation(rx, ry, rz).dot(sp_r)
                inv = 1.0 / dt_i
                acc = [(b - a) * inv for a, b in zip(s0[6:], s1[6:], strict=True)]
                feed = self._lam.dot(acc) - wext
                vel = [(b - a) * inv for a, b in zip(s0[:6], s1[:6], strict=True)]
                damp = self._jt_damp.dot(vel).tolist()
            chunks.append((ox, oy, oz, target_r, feed, damp, self._adm))
        return chunks

    def _step_compiled(self, fp: np.ndarray, v_sp: Velocity) -> None:
        """A control step of v2's law (``track_bandwidth``, ``joint_brake``) by one call of
        ``step_kernel.control_step``: the Jacobian, the model refresh when due and the
        admittance's chunk terms first (``_model_terms``, ``_admitted``), the feedforward
        terms, the chunks and their physics in the kernel; then what it hands back."""
        chunk, step_kernel = _kernels
        m, d, sp_r = self.model, self.data, self._sp_R
        wext = self._wrench.tolist()
        pushed = any(wext)  # the hand's applied wrench is nonzero (_push_at_cup)
        mujoco.mj_jacSite(m, d, self._jacp, self._jacr, self._site)
        v = np.array(v_sp)
        acc, feed, v_list = self._model_terms(v, defer=True)
        terms = (self._lam, self._jt_damp, self._dyn_inv)
        acting = self.version.admittance and (self._adm is not REST or pushed)
        # the admittance's chunk terms compiled where its products' operands are C-ordered
        compiled = acting and all(a.flags.c_contiguous for a in terms)
        chunks = None if compiled else self._admitted(sp_r, wext, HOLD * self._dt)
        par, targets, var, ints = self._par, self._targets, self._var_still, self._ints
        spx, spy, spz = self._sp[:3].tolist()
        par[: chunk.INTEGRAL + 6] = [
            spx, spy, spz, 0.0, 0.0, 0.0, *v_sp, CONTROL_DT, *self._step_head, not self._active,
            not pushed, 0.0, 0.0, *_ZERO6, *(_ZERO7 if feed else self._const), *self._tau_last,
            *_ZERO13, *self._integral,
        ]  # fmt: skip
        if compiled:
            var, states = np.zeros((len(var), step_kernel.VAR)), self._adm_states
            step_kernel.admitted(
                fp, self._adm_coef, np.array(self._adm), self._adm is REST, np.array(wext),
                *terms, sp_r, HOLD * self._dt, CONTROL_DT, var, targets, states,
            )  # fmt: skip
        elif chunks is None:
            targets[:] = sp_r
        else:
            n, dt_i = len(chunks), HOLD * self._dt
            var = np.zeros((n, step_kernel.VAR))
            for i, (ox, oy, oz, target_r, feed_w, damp, _) in enumerate(chunks):
                var[i, :6] = ox, oy, oz, CONTROL_DT - i * dt_i, feed_w is not None, damp is not None
                if feed_w is not None:
                    var[i, 6:12] = feed_w
                if damp is not None:
                    var[i, 12:19] = damp
                targets[i] = target_r
        ints[:] = (
            self._rerun, self.version.joint_room, self._cup_geom, _STAGE_VEL, self._touched, 0,
            acc, feed,
        )  # fmt: skip
        v_prev = np.array(self._v_prev) if acc else v
        code = step_kernel.control_step(*self._step_args(fp, var, v, v_prev))
        self._acc_ff = par[22:28].tolist() if acc else _ZERO6
        if acc:
            self._v_prev = v_list
        if feed:
            self._v_feed, self._const = v_list, par[28:35].tolist()
        if par[18]:  # it integrated
            self._integral = par[chunk.INTEGRAL : chunk.INTEGRAL + 6].tolist()
        self._tau_last = par[35:42].tolist()
        self._touched = bool(ints[step_kernel.TOUCHED])
        if chunks is not None:
            self._adm = chunks[ints[step_kernel.AT_CHUNK] if code else -1][6]
        elif compiled:
            last = states[ints[step_kernel.AT_CHUNK] if code else -1].tolist()
            self._adm = REST if last[12] else tuple(last[:12])
        if code == step_kernel.SINGULAR:
            raise np.linalg.LinAlgError("Singular matrix")
        if code == step_kernel.TRIP:
            self._trip()
            mujoco.mj_kinematics(self.model, self.data)
            mujoco.mj_comPos(self.model, self.data)

    def _step_args(
        self,
        fp: np.ndarray,
        var: np.ndarray,
        v: np.ndarray,
        v_prev: np.ndarray,
        terms: tuple[np.ndarray, ...] | None = None,
    ) -> tuple[Any, ...]:
        """``step_kernel.control_step``'s arguments (``var``: the chunks' own terms; ``v``,
        ``v_prev``: the setpoint's velocity now and before; ``terms``: the model's K, G, M⁻¹,
        Λ, Jᵀ D, J̄ Λ and pull, by default the last refresh's)."""
        kmat, gain, m_inv, lam, jt_damp, dyn_inv, pull_home = terms or (
            self._kmat, self._gain, self._m_inv, self._lam, self._jt_damp, self._dyn_inv,
            self._pull_home,
        )  # fmt: skip
        return (
            fp, self._par, var, self._targets, kmat, gain, m_inv, self._jac, self._caps,
            POSITION_REFLEX, self._ints, self._qpos, self._qvel, self._qacc, self._ctrl,
            self._site_xpos, self._site_xmat, self._objects, self._site, lam, jt_damp, dyn_inv,
            pull_home, JOINT_DAMPING, v, v_prev, 1.0 / CONTROL_DT,
        )  # fmt: skip

    def _load_kernels(self) -> None:
        """Where v2's compiled step runs: look its C functions up (``chunk.functions`` checks
        them, once a process) and load its kernels from numba's disk cache now, as the env is
        built, not inside the first control step's physics (~100 ms, once a process). Nothing
        runs: the kernels are typed on arguments of the types the steps pass."""
        v = self.version
        if not (v.track_bandwidth and v.joint_brake and v.joint_room):
            return
        fp = self._chunk_functions()
        global _loaded
        if fp is None or _loaded:
            return
        import numba

        chunk, step_kernel = _kernels
        n, speed = N_ARM, np.zeros(6)
        refresh = (
            fp, self._mass, self._jac, self._qpos, self._q_home, self._jnt_range, _TWISTS,
            LAMBDA_REG, v.track_bandwidth, K_NULL, D_NULL, K_LIMIT, LIMIT_BAND,
        )  # fmt: skip
        shapes = ((6, 6), (n, 2 * n), (n, n), (6, 6), (n, 6), (n, 6), (n,))
        blank = tuple(np.zeros(shape) for shape in shapes)  # the refresh's outputs' types
        step = self._step_args(fp, self._var_still, speed, speed, blank)
        kernels = [(chunk.refresh, refresh), (step_kernel.control_step, step)]
        if v.admittance:
            wext = np.zeros(6)
            admitted = (
                fp, self._adm_coef, np.zeros(12), True, wext, *blank[3:6], np.eye(3),
                self._dt, CONTROL_DT, self._var_still, self._targets, self._adm_states,
            )  # fmt: skip
            kernels.append((step_kernel.admitted, admitted))
        for kernel, args in kernels:
            if isinstance(kernel, numba.core.dispatcher.Dispatcher):  # not a wrapper (a spy)
                kernel.compile(tuple(numba.typeof(a) for a in args))
        _loaded = True

    def _posture(self) -> tuple[np.ndarray, np.ndarray]:
        """v2's posture spring (``joint_room``) per joint: its stiffness (``K_NULL``, plus
        ``K_LIMIT`` for a twisting joint inside ``LIMIT_BAND``) and its pull at q = 0 (towards
        home, and the band's edge): linear in q until the next model refresh."""
        q = self._qpos
        lo, hi = self._jnt_range
        high, low = q > hi - LIMIT_BAND, q < lo + LIMIT_BAND
        edge = np.where(high, hi - LIMIT_BAND, lo + LIMIT_BAND)
        inside = (high | low) & np.array(LIMIT_JOINTS)
        return K_NULL + K_LIMIT * inside, K_NULL * self._q_home + K_LIMIT * inside * edge

    def _cap_speed(self, s: tuple[float, ...]) -> tuple[float, ...]:
        """The admittance's state with its velocity scaled down (all six axes alike, so its
        direction stays) until no joint needs more than ``ADMITTANCE_SPEED`` of its limit to
        follow it (q̇ = J̄ δ̇, J̄ = M⁻¹ Jᵀ Λ): near a stretched or singular pose a push would
        otherwise spin a joint into the speed reflex."""
        need = self._dyn_inv.dot(s[6:]).tolist()
        over = max(abs(a) / v for a, v in zip(need, self._cap_vlim, strict=True))
        if over <= 1.0:
            return s
        return (*s[:6], *(b / over for b in s[6:]))

    def _ahead(self, tau: list[float], steps: int) -> list[float]:
        """Each joint's speed ``steps`` physics steps on under the torques ``tau``: the last
        step's acceleration plus what the change of torque adds (M⁻¹ Δτ; M at the last model
        refresh). The look-ahead of v2's joint brake: a torque that jumps (the arm springing
        back to its setpoint after a push, a twist) spins the wrist by up to a quarter of its
        limit per physics step, faster than a brake acting on the present speed can catch."""
        delta = [a - b for a, b in zip(tau, self._tau_last, strict=True)]
        acc = self._m_inv.dot(delta).tolist()
        h = steps * self.model.opt.timestep
        return [
            s + h * (a + b)
            for s, a, b in zip(self._qvel.tolist(), self._qacc.tolist(), acc, strict=False)
        ]

    def _brake(self, base: list[float], cap: list[float], tlim: list[float]) -> list[float]:
        """The torques for the next physics step: ``base``, except that the joints whose
        next step's speed (``_ahead``) would pass ``cap`` get the torques that bring them to
        it together (M⁻¹ couples them: capping one joint alone let its neighbour pass its
        limit), each within its motor's range: saturation, never a write of q̇."""
        free = self._ahead(base, 1)  # the speeds under ``base``: the first look and every cut's
        dt = self.model.opt.timestep
        tau = base
        held: list[int] = []
        for _ in range(N_ARM):
            nxt = self._ahead(tau, 1) if held else free
            over = [j for j, (n, b) in enumerate(zip(nxt, cap, strict=False)) if abs(n) > b]
            new = [j for j in over if j not in held]
            if not new:
                break
            held += new
            want = [(math.copysign(cap[j], free[j]) - free[j]) / dt for j in held]
            cut = np.linalg.solve(self._m_inv[np.ix_(held, held)], want).tolist()
            tau = list(base)
            for j, c in zip(held, cut, strict=True):
                tau[j] = min(tlim[j], max(-tlim[j], base[j] + c))
        return tau

    def _step_braked(self, pushed: bool) -> None:
        """``HOLD`` physics steps with v2's joint brake (``BRAKE_FROM``): braked steps
        (:meth:`_braked_steps`) while a wrench pushes, a joint passes a quarter of its limit or
        the look-ahead (``_ahead``) sees one passing ``BRAKE_FROM`` within the chunk; else
        the chunk's torques held, the look-ahead read again after each step
        (:meth:`_watched_steps`)."""
        qd, ctrl = self._qvel, self._ctrl
        if pushed:
            self._braked_steps(pushed, HOLD)
        elif use_fast():  # the same tests in compiled loops (``kernels``)
            from strol_gym.envs.study import kernels

            if kernels.above(qd, self._watch_cap):
                self._braked_steps(pushed, HOLD)
                return
            delta = [a - b for a, b in zip(ctrl.tolist(), self._tau_last, strict=True)]
            extra = self._m_inv.dot(delta)
            h = HOLD * self.model.opt.timestep
            if kernels.ahead_above(qd, self._qacc, extra, h, self._brake_cap):
                self._braked_steps(pushed, HOLD)
            else:
                self._watched_steps()
        elif not any(
            abs(s) > h for s, h in zip(qd.tolist(), self._watch_vlim, strict=False)
        ) and not any(
            abs(s) > b
            for s, b in zip(self._ahead(ctrl.tolist(), HOLD), self._brake_vlim, strict=False)
        ):
            self._watched_steps()
        else:
            self._braked_steps(pushed, HOLD)

    def _watched_steps(self) -> None:
        """``HOLD`` physics steps under the chunk's torques, one ``mj_step`` at a time (the
        bytes of one call of ``HOLD`` steps), the look-ahead to the chunk's end read again
        after each with that step's acceleration: a joint it sees passing ``BRAKE_FROM`` gets
        the brake from the next step on. The chunk's first look extrapolates the last step's
        acceleration, and the arm springing back after pushes in a row speeds up as it goes:
        a wrist joint passed its limit (1.0022x) inside a chunk that look had let through."""
        m, d = self.model, self.data
        tau = self._ctrl.tolist()
        qd, qacc, cap, h = self._qvel, self._qacc, self._brake_vlim, m.opt.timestep
        drift_above: Callable[[np.ndarray, np.ndarray, float, np.ndarray], bool] | None = None
        if use_fast():
            from strol_gym.envs.study import kernels

            drift_above = kernels.drift_above
        for done in range(1, HOLD + 1):
            mujoco.mj_step(m, d)
            self._tau_last = tau
            left = HOLD - done
            # ``_ahead(tau, left)`` inlined: the torques are the last step's, so its M⁻¹ Δτ
            # term is zero (+0.0: M⁻¹'s diagonal is positive), and a speed's magnitude is all
            # that is compared
            if not left:
                continue
            if (
                drift_above(qd, qacc, left * h, self._brake_cap)
                if drift_above is not None
                else any(
                    abs(s + (left * h) * a) > b
                    for s, a, b in zip(qd.tolist(), qacc.tolist(), cap, strict=False)
                )
            ):
                self._note_contact()
                self._braked_steps(False, left)
                return
        self._note_contact()

    def _braked_steps(self, pushed: bool, steps: int) -> None:
        """``steps`` physics steps one ``mj_step`` at a time, a joint's torque capped so that
        its next step's speed stays at ``BRAKE_FROM`` of its limit (:meth:`_brake`), the
        joints' damping cancelled (``JOINT_COMP``), the reflexes watched."""
        m, d, qd, ctrl = self.model, self.data, self._qvel, self._ctrl
        start = self._brake_vlim
        base0 = ctrl.tolist()
        comp = [JOINT_COMP * c for c in JOINT_DAMPING.tolist()]
        tlim, m_inv = self._tlim, self._m_inv
        dt = m.opt.timestep
        for _ in range(steps):
            speeds = qd.tolist()
            base = [b + c * s for b, c, s in zip(base0, comp, speeds, strict=False)]
            near = zip(speeds, self._ahead(base, 1), self._exact_vlim, strict=False)
            if any(abs(s) > e or abs(n) > e for s, n, e in near):
                # Near the brake: the acceleration at this state, not the last one's (a contact
                # made or broken between them jumped a wrist joint by a third of its limit in
                # one step): the position and velocity stages, the acceleration under ``base``,
                # then the brake's torques and the step's end (mj_step1 + mj_step2 = mj_step).
                mujoco.mj_step1(m, d)
                tau = base
                for look in range(3):  # a contact answers the brake's torque too: look again
                    ctrl[:] = self._tau_last = tau
                    mujoco.mj_forwardSkip(m, d, mujoco.mjtStage.mjSTAGE_VEL, 0)
                    if look == 0 and pushed and not self._rerun and self._too_fast():
                        self._trip()
                        return
                    tau = self._brake(tau, start, tlim)
                    if tau == self._tau_last:
                        break
                ctrl[:] = tau
                mujoco.mj_step2(m, d)
            else:
                ctrl[:] = base
                mujoco.mj_step(m, d)
            tau = self._tau_last = ctrl.tolist()
            self._note_contact()
            if self._rerun:
                continue
            if pushed and self.version.joint_room and self._at_limit():
                self._trip()
                return
            # The speed reflex: a joint that would pass its limit at the next step even with
            # its motor's full torque against the motion (the push loads it beyond what the
            # torques can hold) trips it: the brakes lock the arm now. The arm's own torques
            # never trip it (the brake holds them).
            speeds, acc = qd.tolist(), self._qacc.tolist()
            for j, (s, a, r) in enumerate(zip(speeds, acc, self._reflex_vlim, strict=False)):
                if abs(s + dt * a) <= r:
                    continue
                brake = -math.copysign(tlim[j], s) - tau[j]
                if abs(s + dt * (a + m_inv[j, j] * brake)) > r:
                    self._trip()
                    return

    def _at_limit(self) -> bool:
        """Whether a twisting joint is within ``POSITION_REFLEX`` of a position limit, moving
        towards it (the position reflex while a person pushes)."""
        r = POSITION_REFLEX
        return any(
            twists and ((q > hi - r and v > 0.0) or (q < lo + r and v < 0.0))
            for q, v, lo, hi, twists in zip(
                self._qpos.tolist(),
                self._qvel.tolist(),
                self._jnt_low,
                self._jnt_high,
                LIMIT_JOINTS,
                strict=True,
            )
        )

    def _too_fast(self) -> bool:
        """The speed reflex while a person pushes: under the torques about to act (the
        acceleration at the present state) a joint would pass its speed limit at the next
        physics step. The push drives the arm faster than it may go: the Panda stops (its
        joint-velocity reflex) rather than brake against the person; a push the brake held on
        instead read more often off its direction (the cup turned by an object or a joint's
        limit: Task 2, 200 held-out pushes, 18 more read, rotation within 30° 95.0 → 88.2 %)."""
        h = self.model.opt.timestep
        return any(
            abs(s + h * a) > r
            for s, a, r in zip(
                self._qvel.tolist(), self._qacc.tolist(), self._reflex_vlim, strict=False
            )
        )

    def _note_contact(self) -> None:
        """Whether the cup touches an object (``info["contact"]``), after a physics step."""
        d = self.data
        if not d.ncon:
            return
        cup, objects = self._cup_geom, self._object_geoms
        pairs = zip(d.contact.geom1.tolist(), d.contact.geom2.tolist(), strict=True)
        self._touched = self._touched or any(
            (a == cup and b in objects) or (b == cup and a in objects) for a, b in pairs
        )
