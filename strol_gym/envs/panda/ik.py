"""Kinematic control of the Panda's end effector (damped-least-squares IK), for any scene that
includes gymnasium-robotics' Panda (``panda``). Positions are in a task frame: the world frame
shifted by ``lift``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import mujoco
import numpy as np

from strol_gym.compiled import use_fast
from strol_gym.envs.panda.model import EE_SITE, FINGER_OPEN, N_ARM, Q_HOME

IK_ITERS = 6
"""Damped-least-squares iterations per env step (stops early below IK_TOL)."""
IK_TOL = 2e-4
"""Position tolerance of the IK, metres."""
IK_DAMPING = 0.02
IK_ORIENT_GAIN = 0.3
"""Gain of the gripper-down term, which acts only in the null space of the position task."""
IK_POSTURE_GAIN = 0.1
"""Gain of the pull towards the seed table's posture (null space of the position task)."""
IK_RECOVER = 5.0
"""Restart from the reference posture when the error exceeds IK_RECOVER x IK_TOL."""


class PandaIK:
    """Kinematic control of the Panda's end effector: damped-least-squares IK on the arm joints.

    The position task has priority. Two secondary terms act in its null space: "gripper
    down" (the orientation of ``Q_HOME``) and a pull towards a reference posture (the IK seed
    table's configuration nearest the target), which keeps the arm on one continuous IK branch
    away from its joint limits. If an update still misses the target (the arm folded into a
    joint limit), the IK restarts from the reference posture. Joint limits are respected.
    Positions here are in the task frame, whose origin is ``lift`` metres above the world's;
    ``seeds`` is a table of joint configurations over the box [low, high] (``robot_seeds``).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        seeds: np.ndarray | None = None,
        low: np.ndarray | None = None,
        high: np.ndarray | None = None,
        lift: float = 0.0,
    ) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, EE_SITE)
        self.q = self.data.qpos[:N_ARM]  # a view: writing it moves the arm
        self.lo = model.jnt_range[:N_ARM, 0].copy()
        self.hi = model.jnt_range[:N_ARM, 1].copy()
        self.lift = np.array([0.0, 0.0, lift])
        self._jp = np.zeros((3, model.nv))
        self._jr = np.zeros((3, model.nv))
        self._y = np.zeros(3)
        self._damp = IK_DAMPING**2 * np.eye(3)
        self._a = np.zeros((3, 3))
        self._w9 = np.zeros(model.nv)
        self._s = np.zeros(N_ARM)
        self._r = np.zeros(3)
        self._no_ref = np.zeros(N_ARM)
        self._lo_l, self._hi_l = self.lo.tolist(), self.hi.tolist()
        self._lift_l = self.lift.tolist()
        self.seeds = seeds
        if seeds is not None:
            self._seed_low = np.asarray(low, dtype=np.float64)
            self._seed_step = (np.asarray(high) - self._seed_low) / (np.array(seeds.shape[:3]) - 1)
            self._seed_max = np.array(seeds.shape[:3]) - 1
            self._seed_low_l = self._seed_low.tolist()
            self._seed_step_l = self._seed_step.tolist()
            self._seed_top = self._seed_max.tolist()
        self.kernel_gains = (IK_ORIENT_GAIN, IK_POSTURE_GAIN, IK_DAMPING**2, IK_RECOVER)
        """The constants the compiled solve reads (``ik_kernel.solve_arm``), in its order."""
        # The seed table as the compiled solve reads it (an empty one: no table).
        table = np.zeros((0, 1, 1, N_ARM)) if seeds is None else np.asarray(seeds, dtype=np.float64)
        self.seed_args = (
            table,
            *(
                (np.zeros(3), np.ones(3), np.zeros(3, dtype=np.intp))
                if seeds is None
                else (self._seed_low, self._seed_step, self._seed_max.astype(np.intp))
            ),
        )
        self.data.qpos[N_ARM:] = FINGER_OPEN
        self.set_q(Q_HOME)
        # The rotation error to "gripper as in Q_HOME" is linear in the site's xmat (9,):
        # e = ½ (z × z_d + x × x_d) = −½ ([z_d]× z + [x_d]× x).
        rd = self.data.site_xmat[self.site].reshape(3, 3).copy()
        self._orient = np.zeros((3, 9))
        self._orient[:, 2::3] = -0.5 * _skew(rd[:, 2])  # columns of xmat: z is entries 2, 5, 8
        self._orient[:, 0::3] = -0.5 * _skew(rd[:, 0])

    def set_q(self, q: np.ndarray) -> None:
        self.q[:] = q
        mujoco.mj_kinematics(self.model, self.data)

    @property
    def ee(self) -> np.ndarray:
        """The end-effector position in the task frame (a copy)."""
        return self.data.site_xpos[self.site] - self.lift

    def tilt_deg(self) -> float:
        """Angle between the gripper axis and straight down, degrees."""
        z = self.data.site_xmat[self.site][8]
        return float(np.degrees(np.arccos(np.clip(-z, -1.0, 1.0))))

    def reference(self, target: np.ndarray) -> np.ndarray | None:
        """The seed table's configuration nearest ``target`` (task frame), if there is a table."""
        if self.seeds is None:
            return None
        # Plain floats: the same IEEE operations as numpy's elementwise ones (round() rounds
        # half to even, as np.rint), without numpy's per-call cost on three numbers.
        idx = [
            min(max(round((t - lo) / st), 0), top)
            for t, lo, st, top in zip(
                np.asarray(target).tolist(),
                self._seed_low_l,
                self._seed_step_l,
                self._seed_top,
                strict=True,
            )
        ]
        q = self.seeds[idx[0], idx[1], idx[2]]
        return None if math.isnan(q[0]) else q

    def solve(self, target: np.ndarray, iters: int = IK_ITERS, tol: float = IK_TOL) -> float:
        """Move the arm so that the end effector reaches ``target`` (task frame).

        Returns the remaining position error (m).
        """
        if use_fast():  # the same steps in one compiled call, where the kernel can run here
            arm = _solve_arm()
            if arm is not None:
                return arm(self, target, iters, tol)
        world = [t + h for t, h in zip(np.asarray(target).tolist(), self._lift_l, strict=True)]
        ref = self.reference(target)
        err = self._solve(world, iters, tol, ref)
        if err > IK_RECOVER * tol and ref is not None:
            q_prev = self.q.copy()
            self.set_q(ref)
            err_ref = self._solve(world, 8 * iters, tol, ref)
            if err_ref < err:
                err = err_ref
            else:
                self.set_q(q_prev)
        return err

    def _solve(
        self,
        target: np.ndarray | list[float],
        iters: int,
        tol: float,
        ref: np.ndarray | None,
        orient_gain: float = IK_ORIENT_GAIN,
    ) -> float:
        """``iters`` IK iterations towards ``target`` (world frame); returns the error.

        The products of Jacobians stay numpy's (BLAS) calls; the elementwise work on 3 and 7
        numbers is done in plain floats with the same IEEE operations in the same order (numpy's
        per-call cost dominates on so few numbers), so the arm reaches the same bits."""
        m, d, q = self.model, self.data, self.q
        x = d.site_xpos[self.site]
        xmat = d.site_xmat[self.site]
        kernel = solver()
        if kernel is not None:  # the same iterations, compiled (strol_gym.envs.panda.ik_kernel)
            return kernel(
                m._address,
                d._address,
                self.site,
                x,
                xmat,
                q,
                self._jp,
                self._jr,
                self._w9,
                self._orient,
                np.asarray(target, dtype=np.float64),
                iters,
                tol,
                self._no_ref if ref is None else np.asarray(ref, dtype=np.float64),
                ref is not None,
                orient_gain,
                IK_POSTURE_GAIN,
                IK_DAMPING**2,
                self.lo,
                self.hi,
            )
        jp = self._jp[:, :N_ARM]
        tx, ty, tz = target if isinstance(target, list) else np.asarray(target).tolist()
        tol2 = tol * tol
        ref_l = None if ref is None else ref.tolist()
        lo, hi, w9 = self._lo_l, self._hi_l, self._w9
        posture = IK_POSTURE_GAIN
        com_pos, jac_site, mul_t = mujoco.mj_comPos, mujoco.mj_jacSite, mujoco.mju_mulMatTVec
        jp_full, jr_full, site, orient = self._jp, self._jr, self.site, self._orient
        ql = q.tolist()
        for _ in range(iters):
            x0, x1, x2 = x.tolist()
            e = (tx - x0, ty - x1, tz - x2)
            if e[0] * e[0] + e[1] * e[1] + e[2] * e[2] < tol2:
                break
            com_pos(m, d)
            jac_site(m, d, jp_full, jr_full, site)
            # Secondary motion s, projected into the position task's null space:
            # dq = J⁺ e + (I − J⁺J) s = s + Jᵀ (J Jᵀ + λ²I)⁻¹ (e − J s).
            # Jᵣᵀ v: MuJoCo's product sums the 3 terms in order, as numpy's (BLAS) does: the
            # same bits (checked on random matrices); numpy's J Jᵀ and J s fuse multiply-adds
            # and stay numpy's.
            mul_t(w9, jr_full, orient @ xmat)
            w = w9[:N_ARM].tolist()
            if ref_l is None:
                sl = [orient_gain * wi for wi in w]
            else:
                sl = [
                    orient_gain * wi + posture * (ri - qi)
                    for wi, ri, qi in zip(w, ref_l, ql, strict=True)
                ]
            q_new, q_clip = self._update(jp, jp_full, w9, ql, sl, e)
            if q_clip != q_new:  # a joint left its range (or a NaN): the limit step below
                # Joints at a limit drop out (their columns of J and entries of s times 0); the
                # others take over their share.
                free = [float(lj <= qn <= hj) for qn, lj, hj in zip(q_new, lo, hi, strict=True)]
                sl = [si * f for si, f in zip(sl, free, strict=True)]
                jf = jp * np.array(free)
                q_new, q_clip = self._update(jf, jf, w9[:N_ARM], ql, sl, e)
            q[:] = q_clip
            ql = q_clip
            mujoco.mj_kinematics(m, d)
        x0, x1, x2 = x.tolist()
        e0, e1, e2 = tx - x0, ty - x1, tz - x2
        return math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)

    def _update(
        self,
        jp: np.ndarray,
        jt: np.ndarray,
        out: np.ndarray,
        ql: list[float],
        sl: list[float],
        e: tuple[float, float, float],
    ) -> tuple[list[float], list[float]]:
        """One damped-least-squares update of joints ``ql``: q + s + Jᵀ y with
        (J Jᵀ + λ²I) y = e − J s (MuJoCo's Cholesky: no numpy.linalg). ``jp`` is J (3, 7) for
        numpy's products, ``jt`` a contiguous J whose first 7 columns are ``jp`` (MuJoCo's own, or
        ``jp`` itself) for MuJoCo's Jᵀ y into ``out``.
        Returns (the new joints, the new joints clipped to their limits)."""
        a, y, s, r = self._a, self._y, self._s, self._r
        np.matmul(jp, jp.T, out=a)
        a += self._damp
        mujoco.mju_cholFactor(a, 0.0)
        s[:] = sl
        v0, v1, v2 = (jp @ s).tolist()
        r[:] = (e[0] - v0, e[1] - v1, e[2] - v2)
        mujoco.mju_cholSolve(y, a, r)
        mujoco.mju_mulMatTVec(out, jt, y)  # Jᵀ y, 3 terms in order as numpy's
        dq = out[:N_ARM].tolist()
        q_new = [qi + (si + di) for qi, si, di in zip(ql, sl, dq, strict=True)]
        lo, hi = self._lo_l, self._hi_l
        q_clip = [
            hj if qn > hj else (lj if qn < lj else qn)
            for qn, lj, hj in zip(q_new, lo, hi, strict=True)
        ]
        return q_new, q_clip


def solver() -> Callable[..., float] | None:
    """The compiled ``PandaIK._solve`` (``strol_gym.envs.panda.ik_kernel``) when the fast
    kernels are on and it can run here; None: the plain path."""
    if not use_fast():
        return None
    from strol_gym.envs.panda.ik_kernel import solver as compiled_solver

    return compiled_solver()


@functools.cache
def _solve_arm() -> Callable[..., float] | None:
    """``ik_kernel.solve_arm`` where ``solver()`` finds the compiled kernel, else None: looked
    up once (every env step asks)."""
    from strol_gym.envs.panda.ik_kernel import solve_arm
    from strol_gym.envs.panda.ik_kernel import solver as compiled_solver

    return solve_arm if compiled_solver() is not None else None


@functools.cache
def move_arm() -> Callable[..., float] | None:
    """``ik_kernel.move_arm`` (a clipped move and its solve in one compiled call) where
    ``solver()`` finds the compiled kernel, else None: looked up once (every env step asks).
    Only for ``use_fast()`` callers."""
    from strol_gym.envs.panda.ik_kernel import move_arm as compiled_move
    from strol_gym.envs.panda.ik_kernel import solver as compiled_solver

    return compiled_move if compiled_solver() is not None else None


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
