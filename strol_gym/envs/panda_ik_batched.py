"""Damped-least-squares IK for N Panda arms at once, in numpy (the vector Robot env's arm).

The same algorithm as :class:`strol_gym.envs.panda_ik.PandaIK`, step for step (position task
first; "gripper down" and the seed table's posture in its null space; joints at a limit drop
out; a restart from the reference posture when an update misses), with the forward kinematics
and the site Jacobian written out for the Panda's chain of hinge joints instead of one
``mj_kinematics`` / ``mj_jacSite`` call per arm. Each arm stops iterating when it is within
tolerance, as the single IK does, so arm i follows the single IK's iterations; the numbers agree
to rounding (~1e-15), except where a rounding difference flips a threshold test (a near-tie).
"""

from __future__ import annotations

import mujoco
import numpy as np

from strol_gym.envs.panda import N_ARM
from strol_gym.envs.panda_ik import (
    IK_DAMPING,
    IK_ITERS,
    IK_ORIENT_GAIN,
    IK_POSTURE_GAIN,
    IK_RECOVER,
    IK_TOL,
    PandaIK,
)

SINGLE_RETRY = 16
"""Up to this many arms restart (``IK_RECOVER``) one by one through ``PandaIK``; more, batched."""


def _quat_mat(q: np.ndarray) -> np.ndarray:
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, dtype=np.float64))
    return m.reshape(3, 3)


class BatchedPandaIK:
    """N Panda arms' joint angles ``q`` (N, 7) and their end effectors, solved together.

    Built from a :class:`PandaIK` (its model, seed table, joint limits, task-frame lift and
    gripper-down term). The chain is read from the model: each arm joint is a hinge about its
    body's z axis at the body's origin (checked), the end-effector site sits on the last one.
    """

    def __init__(self, ik: PandaIK, n: int) -> None:
        m = ik.model
        jnt = np.arange(N_ARM)
        bodies = m.jnt_bodyid[jnt]
        if not (
            (m.jnt_type[jnt] == mujoco.mjtJoint.mjJNT_HINGE).all()
            and np.allclose(m.jnt_axis[jnt], [0.0, 0.0, 1.0])
            and np.allclose(m.jnt_pos[jnt], 0.0)
            and (m.qpos0[jnt] == 0.0).all()
            and m.site_bodyid[ik.site] == bodies[-1]
        ):
            raise ValueError("BatchedPandaIK needs the Panda's chain of z-axis hinges")
        # The fixed part of the chain up to the first joint's body, then one offset per joint.
        chain = [int(bodies[0])]
        while m.body_parentid[chain[-1]] != 0:
            chain.append(int(m.body_parentid[chain[-1]]))
        rot, pos = np.eye(3), np.zeros(3)
        for b in reversed(chain):
            pos = pos + rot @ m.body_pos[b]
            rot = rot @ _quat_mat(m.body_quat[b])
        self._base_rot, self._base_pos = rot, pos
        self._body_pos = m.body_pos[bodies].copy()  # (7, 3): offsets in the parent's frame
        self._body_rot = np.stack([_quat_mat(m.body_quat[b]) for b in bodies])
        self._body_rot[0] = np.eye(3)  # the first joint's body frame is _base_rot
        self._site_pos = m.site_pos[ik.site].copy()
        self._site_rot = _quat_mat(m.site_quat[ik.site])
        # By columns, a body's frame is Rᵀ of its parent's columns and its origin the parent's
        # origin plus p · columns: both in one (4, 3) matrix per link.
        self._links = np.concatenate(
            [self._body_rot.transpose(0, 2, 1), self._body_pos[:, None]], 1
        )
        self._site_link = np.vstack([self._site_rot.T, self._site_pos])
        self.lo, self.hi = ik.lo.copy(), ik.hi.copy()
        self._lo, self._hi = self.lo[:, None], self.hi[:, None]
        self.lift = ik.lift.copy()
        self.seeds = ik.seeds
        if ik.seeds is not None:
            self._seed_low, self._seed_step = ik._seed_low, ik._seed_step
            self._seed_max = ik._seed_max
        self._orient = ik._orient.copy()
        self._single = ik
        self._damp2 = IK_DAMPING**2
        # Rotations are stored by columns over the batch, cols[k, i, b] = R_b[i, k], so that
        # every product is one small matrix times a (3, 3N) block and every elementwise
        # operation runs over N contiguous numbers.
        self._orient_cols = self._orient.reshape(3, 3, 3).transpose(0, 2, 1).reshape(3, 9)
        self.n = int(n)
        self._q = np.tile(ik.q[:, None], (1, self.n))  # (7, N)
        self.q = self._q.T  # (N, 7), a view: writing it moves the arms
        self._site = np.zeros((3, self.n))
        self._site_cols = np.zeros((3, 3, self.n))
        self._axes = np.zeros((N_ARM, 3, self.n))
        self._anchors = np.zeros((N_ARM, 3, self.n))
        self.forward()

    # ------------------------------------------------------------------ kinematics
    def _fk(self, q: np.ndarray) -> tuple[np.ndarray, ...]:
        """Site position (3, B), site rotation columns (3, 3, B), joint axes and anchors
        (7, 3, B) from joint angles q (7, B)."""
        b = q.shape[1]
        c, s = np.cos(q), np.sin(q)
        cols = np.repeat(self._base_rot.T[:, :, None], b, axis=2)
        pos = np.repeat(self._base_pos[:, None], b, axis=1)
        axes = np.empty((N_ARM, 3, b))
        anchors = np.empty((N_ARM, 3, b))
        frame = cols
        for j in range(N_ARM):
            if j:
                # One product gives the next body's frame (rows 0-2) and its offset (row 3).
                out = (self._links[j] @ cols.reshape(3, -1)).reshape(4, 3, b)
                frame = out[:3]
                pos = pos + out[3]
            # The hinge turns the body frame about its z axis by q_j.
            cols = np.empty((3, 3, b))
            np.multiply(frame[0], c[j], out=cols[0])
            cols[0] += s[j] * frame[1]
            np.multiply(frame[1], c[j], out=cols[1])
            cols[1] -= s[j] * frame[0]
            cols[2] = frame[2]
            axes[j] = frame[2]
            anchors[j] = pos
        out = (self._site_link @ cols.reshape(3, -1)).reshape(4, 3, b)
        site, site_cols = pos + out[3], out[:3]
        return site, site_cols, axes, anchors

    def forward(self, rows: np.ndarray | slice = slice(None)) -> None:
        """Recompute the kinematics of arms ``rows`` from ``q``."""
        site, cols, axes, anchors = self._fk(self._q[:, rows])
        self._site[:, rows], self._site_cols[..., rows] = site, cols
        self._axes[..., rows], self._anchors[..., rows] = axes, anchors

    @property
    def ee(self) -> np.ndarray:
        """End-effector positions in the task frame, (N, 3) (a copy)."""
        return self._site.T - self.lift

    @property
    def site_xmat(self) -> np.ndarray:
        """End-effector rotation matrices, (N, 3, 3) (a copy)."""
        return self._site_cols.transpose(2, 1, 0).copy()

    def reference(self, target: np.ndarray) -> np.ndarray:
        """The seed table's configuration nearest each target, (B, 7); NaN rows: none."""
        if self.seeds is None:
            return np.full((len(target), N_ARM), np.nan)
        idx = np.rint((target - self._seed_low) / self._seed_step).astype(int)
        np.minimum(np.maximum(idx, 0), self._seed_max, out=idx)
        return self.seeds[idx[:, 0], idx[:, 1], idx[:, 2]]

    # ------------------------------------------------------------------ IK
    def solve(
        self, target: np.ndarray, rows: np.ndarray, iters: int = IK_ITERS, tol: float = IK_TOL
    ) -> np.ndarray:
        """Move arms ``rows`` (indices) to ``target`` (len(rows), 3; task frame), as
        ``PandaIK.solve`` does for one arm. Returns the remaining errors (m)."""
        world = target + self.lift
        ref = self.reference(target)
        has_ref = ~np.isnan(ref[:, 0])
        err = self._solve(world.T, rows, iters, tol, ref.T, has_ref)
        retry = np.flatnonzero((err > IK_RECOVER * tol) & has_ref)
        if 0 < len(retry) <= SINGLE_RETRY:
            # A restart runs 8x the iterations, usually for an arm or two that cannot reach
            # their target: numpy's per-call cost on so few rows exceeds MuJoCo's own kinematics,
            # so the single IK itself does them.
            ik = self._single
            for k in retry:
                ik.set_q(ref[k])
                err_ref = ik._solve(world[k], 8 * iters, tol, ref[k])
                if err_ref < err[k]:
                    err[k] = err_ref
                    self._q[:, rows[k]] = ik.q
            self.forward(rows[retry])
        elif len(retry):
            sub = rows[retry]
            q_prev = self._q[:, sub].copy()
            self._q[:, sub] = ref[retry].T
            self.forward(sub)
            err_ref = self._solve(world[retry].T, sub, 8 * iters, tol, ref[retry].T, has_ref[retry])
            better = err_ref < err[retry]
            err[retry[better]] = err_ref[better]
            worse = sub[~better]
            if len(worse):
                self._q[:, worse] = q_prev[:, ~better]
                self.forward(worse)
        return err

    def _solve(
        self,
        target: np.ndarray,
        rows: np.ndarray,
        iters: int,
        tol: float,
        ref: np.ndarray,
        has_ref: np.ndarray,
    ) -> np.ndarray:
        """``iters`` iterations for arms ``rows`` towards world-frame ``target`` (3, B)."""
        # While most arms iterate, all rows are computed (slices, no gathers or scatters) and
        # only the iterating ones move; once fewer than half do, just those rows.
        full = len(rows) == self.n and bool((rows == np.arange(self.n)).all())
        moving = np.ones(len(rows), dtype=bool)
        live = np.arange(len(rows))  # positions (in rows) of the arms still iterating
        for _ in range(iters):
            if full:
                ep = target - self._site
                moving &= ~((ep * ep).sum(axis=0) < tol * tol)
                if 2 * moving.sum() >= self.n:
                    self._iterate(slice(None), ep, ref, has_ref, moving)
                    continue
                full, live = False, np.flatnonzero(moving)
                if not len(live):
                    break
            idx = rows[live]
            ep = target[:, live] - self._site[:, idx]
            near = (ep * ep).sum(axis=0) < tol * tol
            if near.any():
                keep = ~near
                live, idx, ep = live[keep], idx[keep], ep[:, keep]
                if not len(live):
                    break
            self._iterate(idx, ep, ref[:, live], has_ref[live], None)
        ep = target - self._site[:, rows]
        return np.sqrt((ep * ep).sum(axis=0))

    def _iterate(
        self,
        idx: np.ndarray | slice,
        ep: np.ndarray,
        ref: np.ndarray,
        has_ref: np.ndarray,
        moving: np.ndarray | None,
    ) -> None:
        """One IK iteration of arms ``idx`` (errors ``ep``); with ``moving``, only those move."""
        q = self._q[:, idx]
        axes = self._axes[..., idx]  # (7, 3, B): joint j's axis, the rotational Jacobian
        d = self._site[:, idx] - self._anchors[..., idx]
        jp = np.empty_like(axes)  # (7, 3, B): joint j's column of the position Jacobian
        jp[:, 0] = axes[:, 1] * d[:, 2] - axes[:, 2] * d[:, 1]
        jp[:, 1] = axes[:, 2] * d[:, 0] - axes[:, 0] * d[:, 2]
        jp[:, 2] = axes[:, 0] * d[:, 1] - axes[:, 1] * d[:, 0]
        v = self._orient_cols @ self._site_cols[..., idx].reshape(9, -1)  # (3, B)
        s = IK_ORIENT_GAIN * (axes * v).sum(axis=1)
        if has_ref.all():
            s += IK_POSTURE_GAIN * (ref - q)
        elif has_ref.any():
            s[:, has_ref] += IK_POSTURE_GAIN * (ref[:, has_ref] - q[:, has_ref])
        q_new = q + self._step(jp, s, ep)
        blocked = (q_new < self._lo) | (q_new > self._hi)
        hit = blocked.any(axis=0)
        if moving is not None:
            hit &= moving
        if hit.any():
            free = ~blocked[:, hit]
            s_h = s[:, hit] * free
            jp_h = jp[..., hit] * free[:, None]
            q_new[:, hit] = q[:, hit] + self._step(jp_h, s_h, ep[:, hit])
        q_new = np.minimum(np.maximum(q_new, self._lo), self._hi)
        if moving is not None and not moving.all():
            q_new = np.where(moving, q_new, q)
        self._q[:, idx] = q_new
        self.forward(idx)

    def _step(self, jp: np.ndarray, s: np.ndarray, ep: np.ndarray) -> np.ndarray:
        """dq = s + Jᵀ (J Jᵀ + λ²I)⁻¹ (e − J s) per arm; ``jp`` is J by columns (7, 3, B)."""
        a00, a11, a22 = ((jp[:, i] * jp[:, i]).sum(axis=0) + self._damp2 for i in range(3))
        a10 = (jp[:, 1] * jp[:, 0]).sum(axis=0)
        a20 = (jp[:, 2] * jp[:, 0]).sum(axis=0)
        a21 = (jp[:, 2] * jp[:, 1]).sum(axis=0)
        rhs = ep - (jp * s[:, None]).sum(axis=0)
        # Cholesky of the symmetric positive definite 3x3 system, elementwise over the batch.
        l00 = np.sqrt(a00)
        l10, l20 = a10 / l00, a20 / l00
        l11 = np.sqrt(a11 - l10 * l10)
        l21 = (a21 - l20 * l10) / l11
        l22 = np.sqrt(a22 - l20 * l20 - l21 * l21)
        z0 = rhs[0] / l00
        z1 = (rhs[1] - l10 * z0) / l11
        z2 = (rhs[2] - l20 * z0 - l21 * z1) / l22
        y2 = z2 / l22
        y1 = (z1 - l21 * y2) / l11
        y0 = (z0 - l10 * y1 - l20 * y2) / l00
        return s + jp[:, 0] * y0 + jp[:, 1] * y1 + jp[:, 2] * y2
