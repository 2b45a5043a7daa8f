"""Damped-least-squares IK for N Panda arms at once, in numpy (the vector Robot env's arm).

The same algorithm as :class:`strol_gym.envs.panda.ik.PandaIK`, step for step (position task
first; "gripper down" and the seed table's posture in its null space; joints at a limit drop
out; a restart from the reference posture when an update misses), with the forward kinematics
and the site Jacobian written out for the Panda's chain of hinge joints instead of one
``mj_kinematics`` / ``mj_jacSite`` call per arm. Each arm stops iterating when it is within
tolerance, as the single IK does, so arm i follows the single IK's iterations; the numbers agree
to rounding (~1e-15), except where a rounding difference flips a threshold test (a near-tie).

Every array holds the arms along its last axis, so that each operation runs over contiguous
numbers of all the arms at once and an iteration is a fixed, small number of numpy calls
(their per-call cost, not the arithmetic, is what a batch of a few hundred arms pays).

With the compiled kernels on (``strol_gym.compiled``), sets of at most ``HANDOFF`` arms (the
vector env's 1,024) and the restarts run in ``strol_gym.envs.panda.ik_kernel``, which repeats
these numbers to the bit (checked once per process, ``compiled_kernels``).
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from strol_gym.compiled import use_fast
from strol_gym.envs.panda.ik import (
    IK_DAMPING,
    IK_ITERS,
    IK_ORIENT_GAIN,
    IK_POSTURE_GAIN,
    IK_RECOVER,
    IK_TOL,
    PandaIK,
)
from strol_gym.envs.panda.ik_step import ALL_FREE, dls_step
from strol_gym.envs.panda.model import N_ARM

SINGLE_RETRY = 64
"""Up to this many arms restart (``IK_RECOVER``) one by one (``BatchedPandaIK._restart``, ~30 µs
an iteration); more, batched (~0.5 ms an iteration however few arms are left, and a restart
runs until its slowest arm converges or 8x the iterations)."""
COMPACT = 0.5
"""A set of arms iterates together (the converged ones held still) while at least this fraction
of it still iterates; below, a compact copy of just those goes on."""
HANDOFF = 1024
"""With the compiled kernels, a set of at most this many arms goes on in the compiled loop
(``ik_kernel.batched_solve``, one arm at a time); a larger one in numpy until it is this small:
the same numbers either way. Measured on the vector Robot env without a human at N = 1024, all
arms compiled cost 1.2 chains a sub-env step against 1.7 with sets above 192 in numpy
(``benchmarks/speed/chains.py``); larger sets were not measured."""
AGREE_ARMS = 384
"""How many arms ``compiled_kernels`` checks, handing over from numpy at half of them."""


def _quat_mat(q: np.ndarray) -> np.ndarray:
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, dtype=np.float64))
    return m.reshape(3, 3)


class _Arms:
    """Joint angles and kinematics of B arms: q (7, B), the site's position (3, B) and rotation
    by columns (3, 3, B), the joints' axes and anchors (7, 3, B)."""

    __slots__ = ("anchors", "axes", "cols", "q", "site")

    def __init__(
        self,
        q: np.ndarray,
        site: np.ndarray,
        cols: np.ndarray,
        axes: np.ndarray,
        anchors: np.ndarray,
    ) -> None:
        self.q, self.site, self.cols, self.axes, self.anchors = q, site, cols, axes, anchors

    @classmethod
    def empty(cls, b: int) -> _Arms:
        return cls(
            np.empty((N_ARM, b)),
            np.empty((3, b)),
            np.empty((3, 3, b)),
            np.empty((N_ARM, 3, b)),
            np.empty((N_ARM, 3, b)),
        )

    def take(self, sel: np.ndarray) -> _Arms:
        """Arms ``sel`` (indices or a mask), a copy."""
        if getattr(sel, "dtype", None) == np.bool_:
            return _Arms(*(np.compress(sel, a, axis=-1) for a in self._all()))
        return _Arms(*(np.take(a, sel, axis=-1) for a in self._all()))

    def put(self, sel: np.ndarray | slice, other: _Arms) -> None:
        """Write ``other``'s arms into arms ``sel``."""
        for a, b in zip(self._all(), other._all(), strict=True):
            a[..., sel] = b

    def _all(self) -> tuple[np.ndarray, ...]:
        return self.q, self.site, self.cols, self.axes, self.anchors


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
        # Rotations are stored by columns, cols[k, i] = R[i, k]. The first joint's body frame.
        self._base_cols, self._base_pos = rot.T.copy(), pos
        body_pos = m.body_pos[bodies]  # (7, 3): offsets in the parent's frame
        body_rot = np.stack([_quat_mat(m.body_quat[b]) for b in bodies])
        # By columns, a body's frame is Rᵀ of its parent's columns and its origin the parent's
        # origin plus p · columns: both in one (4, 3) matrix per link, one product per joint.
        self._links = np.concatenate([body_rot.transpose(0, 2, 1), body_pos[:, None]], 1)
        site_rot = _quat_mat(m.site_quat[ik.site])
        self._site_link = np.vstack([site_rot.T, m.site_pos[ik.site]])
        self.lo, self.hi = ik.lo.copy(), ik.hi.copy()
        self._lo, self._hi = self.lo[:, None], self.hi[:, None]
        self.lift = ik.lift.copy()
        self.seeds = ik.seeds
        if ik.seeds is not None:
            self._seed_low, self._seed_step = ik._seed_low, ik._seed_step
            self._seed_max = ik._seed_max
        self._orient = ik._orient.copy()
        self._orient6 = self._orient[:, [0, 2, 3, 5, 6, 8]]
        self._orient_l = self._orient6.tolist()
        if np.any(self._orient[:, [1, 4, 7]]):
            raise ValueError("the gripper-down term must not read xmat's entries 1, 4, 7")
        self._lo_l, self._hi_l = self.lo.tolist(), self.hi.tolist()
        self._single = ik
        self._damp2 = IK_DAMPING**2
        # The gripper-down term acts on the site's rotation by columns (9, B).
        self._orient_cols = self._orient.reshape(3, 3, 3).transpose(0, 2, 1).reshape(3, 9)
        self.n = int(n)
        self._arms = _Arms.empty(self.n)
        self._arms.q[:] = ik.q[:, None]
        self._q = self._arms.q  # (7, N)
        self.q = self._q.T  # (N, 7), a view: writing it moves the arms
        self._compiled: bool | None = None
        """Whether the compiled kernels run (None: as ``compiled_kernels`` says, at each call)."""
        self._handoff = HANDOFF
        """Sets of at most this many arms go in the compiled loop (``HANDOFF``)."""
        self.forward()

    def _kernels(self) -> Any:
        """``strol_gym.envs.panda.ik_lanes`` when its N-arm kernels run here, else None."""
        if self._compiled is False or (self._compiled is None and not compiled_kernels(self)):
            return None
        from strol_gym.envs.panda import ik_lanes

        return ik_lanes

    def _chain(self) -> tuple[np.ndarray, ...]:
        """The chain's constants as ``ik_kernel``'s forward kinematics reads them."""
        return self._base_cols, self._base_pos, self._links, self._site_link

    # ------------------------------------------------------------------ kinematics
    def _fk(self, arms: _Arms) -> None:
        """Recompute ``arms``' kinematics from their joint angles, in place."""
        q, axes, anchors = arms.q, arms.axes, arms.anchors
        b = q.shape[1]
        c = np.cos(q)
        sn = np.empty((N_ARM, 2, 1, b))  # (s, −s) per joint
        np.sin(q, out=sn[:, 0, 0])
        np.negative(sn[:, 0, 0], out=sn[:, 1, 0])
        rot = np.empty((3, 3, b))
        tmp = np.empty((2, 3, b))
        frame = np.empty((4, 3, b))
        base = self._base_cols[:, :, None]
        f, swapped = base, base[1::-1]
        axes[0] = base[2]
        anchors[0] = self._base_pos[:, None]
        for j in range(N_ARM):
            if j:
                # One product gives the next body's frame (rows 0-2) and its offset (row 3).
                np.matmul(self._links[j], rot.reshape(3, -1), out=frame.reshape(4, -1))
                np.add(anchors[j - 1], frame[3], out=anchors[j])
                axes[j] = frame[2]
                f, swapped = frame, frame[1::-1]
            # The hinge turns the body frame about its z axis by q_j:
            # x' = c x + s y, y' = c y − s x, z' = z.
            np.multiply(f[:2], c[j], out=rot[:2])
            np.multiply(swapped, sn[j], out=tmp)
            rot[:2] += tmp
            rot[2] = axes[j]
        np.matmul(self._site_link, rot.reshape(3, -1), out=frame.reshape(4, -1))
        arms.cols[:] = frame[:3]
        np.add(anchors[-1], frame[3], out=arms.site)

    def forward(self, rows: np.ndarray | slice = slice(None)) -> None:
        """Recompute the kinematics of arms ``rows`` from ``q``."""
        idx = np.arange(self.n)[rows]
        kernels = self._kernels() if len(idx) <= self._handoff else None
        if kernels is not None:
            a = self._arms
            kernels.batched_forward(a.q, a.site, a.cols, a.axes, a.anchors, idx, *self._chain())
            return
        if (isinstance(rows, slice) and rows == slice(None)) or self._all_rows(rows):
            self._fk(self._arms)
            return
        arms = _Arms.empty(len(idx))
        arms.q[:] = self._q[:, rows]
        self._fk(arms)
        self._arms.put(rows, arms)

    def _all_rows(self, rows: np.ndarray | slice) -> bool:
        """Whether index array ``rows`` is every arm in order (then slices do, in place)."""
        return (
            not isinstance(rows, slice)
            and len(rows) == self.n
            and bool((rows == np.arange(self.n)).all())
        )

    @property
    def ee(self) -> np.ndarray:
        """End-effector positions in the task frame, (N, 3) (a copy)."""
        return self._arms.site.T - self.lift

    @property
    def site_xmat(self) -> np.ndarray:
        """End-effector rotation matrices, (N, 3, 3) (a copy)."""
        return self._arms.cols.transpose(2, 1, 0).copy()

    def reference(self, target: np.ndarray) -> np.ndarray:
        """The seed table's configuration nearest each target, (B, 7); NaN rows: none."""
        if self.seeds is None:
            return np.full((len(target), N_ARM), np.nan)
        kernels = self._kernels()
        if kernels is not None:
            out = np.empty((len(target), N_ARM))
            kernels.references(
                np.ascontiguousarray(target, dtype=np.float64), self.seeds, self._seed_low,
                self._seed_step, self._seed_max, out,
            )  # fmt: skip
            return out
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
            # their target: numpy's per-call cost on so few arms exceeds MuJoCo's own
            # kinematics, so each restarts alone on the single IK's model (_restart).
            ik = self._single
            for k in retry:
                ik.set_q(ref[k])
                err_ref = self._restart(world[k], 8 * iters, tol, ref[k])
                if err_ref < err[k]:
                    err[k] = err_ref
                    self._from_single(rows[k])
        elif len(retry):
            sub = rows[retry]
            prev = self._arms.take(sub)
            self._q[:, sub] = ref[retry].T
            self.forward(sub)
            errs_ref = self._solve(
                world[retry].T, sub, 8 * iters, tol, ref[retry].T, has_ref[retry]
            )
            better = errs_ref < err[retry]
            err[retry[better]] = errs_ref[better]
            if not better.all():
                self._arms.put(sub[~better], prev.take(~better))
        return err

    def _from_single(self, r: int) -> None:
        """Arm ``r`` takes the single IK's posture and MuJoCo's kinematics of it."""
        ik, arms = self._single, self._arms
        d = ik.data
        arms.q[:, r] = ik.q
        arms.site[:, r] = d.site_xpos[ik.site]
        arms.cols[..., r] = d.site_xmat[ik.site].reshape(3, 3).T
        arms.axes[..., r] = d.xaxis[:N_ARM]
        arms.anchors[..., r] = d.xanchor[:N_ARM]

    def _restart(self, target: np.ndarray, iters: int, tol: float, ref: np.ndarray) -> float:
        """``PandaIK._solve`` for one arm, from the single IK's posture, towards world-frame
        ``target``: MuJoCo's kinematics and site Jacobian (as the single IK), the 3x7 algebra of
        ``_iterate`` in plain floats, one pass over the joints (numpy's per-call cost dominates
        on so few numbers). Returns the remaining error; the arm is left in the single IK's
        ``q``."""
        ik = self._single
        m, d, site = ik.model, ik.data, ik.site
        x, xmat, jac_p, jac_r = d.site_xpos[site], d.site_xmat[site], ik._jp, ik._jr
        kernels = self._kernels()
        if kernels is not None:
            fp = kernels.addresses()
            og, pg, damp, lo, hi = IK_ORIENT_GAIN, IK_POSTURE_GAIN, self._damp2, self.lo, self.hi
            return kernels.restart(
                fp, m._address, d._address, site, x, xmat, ik.q, jac_p, jac_r, self._orient6,
                target, iters, tol, ref, og, pg, damp, lo, hi,
            )  # fmt: skip
        jp, jr = jac_p[:, :N_ARM], jac_r[:, :N_ARM]
        tx, ty, tz = target.tolist()
        ref = ref.tolist()
        tol2, damp = tol * tol, self._damp2
        og, pg = IK_ORIENT_GAIN, IK_POSTURE_GAIN
        lo, hi = self._lo_l, self._hi_l
        o00, o02, o03, o05, o06, o08 = self._orient_l[0]
        o10, o12, o13, o15, o16, o18 = self._orient_l[1]
        o20, o22, o23, o25, o26, o28 = self._orient_l[2]
        q = ik.q.tolist()
        q_new = [0.0] * N_ARM
        for _ in range(iters):
            x0, x1, x2 = x.tolist()
            e0, e1, e2 = tx - x0, ty - x1, tz - x2
            if e0 * e0 + e1 * e1 + e2 * e2 < tol2:
                break
            mujoco.mj_comPos(m, d)
            mujoco.mj_jacSite(m, d, jac_p, jac_r, site)
            j0, j1, j2 = jp.tolist()
            m0, _, m2, m3, _, m5, m6, _, m8 = xmat.tolist()
            # The gripper-down term's rotation error (its matrix is 0 on xmat's entries 1, 4, 7).
            v0 = o00 * m0 + o02 * m2 + o03 * m3 + o05 * m5 + o06 * m6 + o08 * m8
            v1 = o10 * m0 + o12 * m2 + o13 * m3 + o15 * m5 + o16 * m6 + o18 * m8
            v2 = o20 * m0 + o22 * m2 + o23 * m3 + o25 * m5 + o26 * m6 + o28 * m8
            s = [
                og * (a * v0 + b * v1 + c * v2) + pg * (rj - qj)
                for a, b, c, rj, qj in zip(*jr.tolist(), ref, q, strict=True)
            ]
            dls_step(q, j0, j1, j2, s, e0, e1, e2, damp, ALL_FREE, q_new)
            free = [lj <= qj <= hj for qj, lj, hj in zip(q_new, lo, hi, strict=True)]
            if not all(free):
                # Joints at a limit drop out (their columns of J and entries of s times 0).
                dls_step(q, j0, j1, j2, s, e0, e1, e2, damp, free, q_new)
            q = [
                hj if qj > hj else (lj if qj < lj else qj)
                for qj, lj, hj in zip(q_new, lo, hi, strict=True)
            ]
            ik.q[:] = q
            mujoco.mj_kinematics(m, d)
        x0, x1, x2 = x.tolist()
        e0, e1, e2 = tx - x0, ty - x1, tz - x2
        return math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)

    def _solve(
        self,
        target: np.ndarray,
        rows: np.ndarray,
        iters: int,
        tol: float,
        ref: np.ndarray,
        has_ref: np.ndarray,
    ) -> np.ndarray:
        """``iters`` iterations for arms ``rows`` towards world-frame ``target`` (3, B).

        The arms iterate as a set (all of them in place, or a compact copy of ``rows``), the
        converged ones held still, while enough of the set still iterates; below
        ``COMPACT`` of it, a smaller copy of just those goes on (a gather, and the others'
        state written back), so that few arms don't pay for many."""
        tol2 = tol * tol
        kernels = self._kernels()
        idx: np.ndarray | None
        if self._all_rows(rows):
            arms, idx = self._arms, None  # in place
        else:
            arms, idx = self._arms.take(rows), rows
        moving = np.ones(len(rows), dtype=bool)
        tgt = target
        # None: every arm has a reference posture
        ref_mask: np.ndarray | None = None if has_ref.all() else has_ref
        for it in range(iters):
            if kernels is not None and len(moving) <= self._handoff:
                # The compiled kernel goes on from here, in the same lockstep, on self._arms.
                if idx is not None:
                    self._arms.put(idx, arms)
                a, here = self._arms, rows if idx is None else idx
                kernels.batched_solve(
                    a.q, a.site, a.cols, a.axes, a.anchors, np.asarray(here, dtype=np.intp),
                    np.ascontiguousarray(tgt), iters - it, tol, np.ascontiguousarray(ref),
                    np.ones(len(moving), dtype=bool) if ref_mask is None else ref_mask,
                    moving, *self._chain(), self._orient_cols, IK_ORIENT_GAIN,
                    IK_POSTURE_GAIN, self._damp2, self.lo, self.hi, COMPACT,
                )  # fmt: skip
                idx = None
                break
            ep = tgt - arms.site
            moving &= np.einsum("ib,ib->b", ep, ep) >= tol2  # |e|², summed in order
            live = int(moving.sum())
            if not live:
                break
            if live < COMPACT * len(moving):
                keep = moving
                if idx is None:
                    idx = rows[keep]
                else:
                    self._arms.put(idx[~keep], arms.take(~keep))
                    idx = idx[keep]
                arms = arms.take(keep)
                tgt, ep, ref = tgt[:, keep], ep[:, keep], ref[:, keep]
                if ref_mask is not None:
                    ref_mask = ref_mask[keep]
                moving = np.ones(live, dtype=bool)
            self._iterate(arms, ep, ref, ref_mask, None if live == len(moving) else moving)
        if idx is not None:
            self._arms.put(idx, arms)
        ep = target - self._arms.site[:, rows]
        return np.sqrt((ep * ep).sum(axis=0))

    def _iterate(
        self,
        arms: _Arms,
        ep: np.ndarray,
        ref: np.ndarray,
        has_ref: np.ndarray | None,
        moving: np.ndarray | None,
    ) -> None:
        """One IK iteration of ``arms`` (errors ``ep``), in place; with ``moving``, only those
        move; ``has_ref`` None: every arm has a reference posture."""
        q, axes = arms.q, arms.axes
        b = q.shape[1]
        # The position Jacobian's column j: axis_j × (site − anchor_j), (7, 3, B).
        d = arms.site - arms.anchors
        jp = np.empty((N_ARM, 3, b))
        tmp = np.empty((N_ARM, b))
        for i, k, m in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
            np.multiply(axes[:, k], d[:, m], out=jp[:, i])
            np.multiply(axes[:, m], d[:, k], out=tmp)
            jp[:, i] -= tmp
        # Secondary motion: gripper down (Jᵣᵀ of the rotation error; Jᵣ's columns are the axes)
        # and the pull towards the reference posture.
        v = self._orient_cols @ arms.cols.reshape(9, -1)  # (3, B)
        s = np.einsum("jib,ib->jb", axes, v)
        s *= IK_ORIENT_GAIN
        if has_ref is None:
            s += IK_POSTURE_GAIN * (ref - q)
        elif has_ref.any():
            s[:, has_ref] += IK_POSTURE_GAIN * (ref[:, has_ref] - q[:, has_ref])
        q_new = self._step(jp, s, ep)
        if moving is not None:
            q_new *= moving  # the others stay where they are (q + 0, within their limits)
        q_new += q
        blocked = (q_new < self._lo) | (q_new > self._hi)
        hit = blocked.any(axis=0)
        if hit.any():
            # Joints at a limit drop out (their columns of J and entries of s times 0).
            hit = np.flatnonzero(hit)
            free = ~np.take(blocked, hit, axis=1)
            jp_h = np.take(jp, hit, axis=2)
            jp_h *= free[:, None]
            s_h = np.take(s, hit, axis=1)
            s_h *= free
            q_h = self._step(jp_h, s_h, np.take(ep, hit, axis=1))
            q_h += np.take(q, hit, axis=1)
            q_new[:, hit] = q_h
        np.maximum(q_new, self._lo, out=q_new)
        np.minimum(q_new, self._hi, out=q)
        self._fk(arms)

    def _step(self, jp: np.ndarray, s: np.ndarray, ep: np.ndarray) -> np.ndarray:
        """dq = s + Jᵀ (J Jᵀ + λ²I)⁻¹ (e − J s) per arm; ``jp`` is J by columns (7, 3, B)."""
        # einsum sums over the joints in order, as numpy's sums and the single IK's products.
        a = np.einsum("jib,jkb->ikb", jp, jp)  # J Jᵀ, (3, 3, B)
        a00, a11, a22 = a[0, 0] + self._damp2, a[1, 1] + self._damp2, a[2, 2] + self._damp2
        a10, a20, a21 = a[1, 0], a[2, 0], a[2, 1]
        rhs = ep - np.einsum("jib,jb->ib", jp, s)
        # Cholesky of the symmetric positive definite 3x3 system, elementwise over the batch.
        l00 = np.sqrt(a00)
        l10, l20 = a10 / l00, a20 / l00
        l11 = np.sqrt(a11 - l10 * l10)
        l21 = (a21 - l20 * l10) / l11
        l22 = np.sqrt(a22 - l20 * l20 - l21 * l21)
        y = np.empty((3, jp.shape[2]))
        z0 = rhs[0] / l00
        z1 = (rhs[1] - l10 * z0) / l11
        np.divide((rhs[2] - l20 * z0 - l21 * z1) / l22, l22, out=y[2])
        np.divide(z1 - l21 * y[2], l11, out=y[1])
        np.divide(z0 - l10 * y[1] - l20 * y[2], l00, out=y[0])
        # Jᵀ y sums its 3 terms in order, as the single IK's product does; then s + Jᵀ y.
        dq = np.einsum("jib,ib->jb", jp, y)
        dq += s
        return dq


_AGREES: bool | None = None
"""Whether the compiled N-arm kernels reach the plain path's bits in this process (checked once,
by ``compiled_kernels``)."""


def compiled_kernels(ik: BatchedPandaIK) -> bool:
    """Whether ``ik``'s arms take the compiled kernels: the fast kernels are on, the single IK's
    kernel runs here (MuJoCo's binding and symbols, this BLAS), and the N-arm kernels reach the
    plain path's bits on 384 arms from random postures towards random targets, near and out of
    reach (limit steps, both kinds of restart, numpy's lockstep handing over to the compiled
    one). Checked once per process."""
    global _AGREES
    if not use_fast():
        return False
    if _AGREES is None:
        from strol_gym.envs.panda import ik_kernel

        _AGREES = False  # while the check builds its own arms
        try:
            _AGREES = ik_kernel.addresses() is not None and _agrees(ik._single)
        except Exception:  # a numba that cannot compile a kernel here: the plain path runs
            _AGREES = False
    return _AGREES


def _agrees(single: PandaIK, n: int = AGREE_ARMS) -> bool:
    """The plain and the compiled N-arm IK on the same arms and targets: the same bytes?"""
    q0 = single.q.copy()
    rng = np.random.default_rng(0)
    lo, hi = single.lo, single.hi
    arms = [BatchedPandaIK(single, n) for _ in range(2)]
    start = lo + (hi - lo) * rng.random((n, N_ARM))
    results = []
    for ik, fast in zip(arms, (False, True), strict=True):
        ik._compiled = fast
        ik._handoff = n // 2  # numpy first, then the compiled loop: the handover checked too
        ik.q[:] = start
        ik.forward()
        out: list[np.ndarray] = []
        every, third = np.arange(n), np.arange(0, n, 3)
        for spread, rows in ((0.15, every), (2.0, every), (2.0, third), (0.6, every)):
            target = np.random.default_rng(len(out)).normal(0.0, spread, (len(rows), 3))
            target += (0.45, 0.0, 0.35)
            out.append(ik.solve(target, rows))
        a = ik._arms
        results.append(
            b"".join(x.tobytes() for x in (*out, a.q, a.site, a.cols, a.axes, a.anchors))
        )
    single.set_q(q0)
    return results[0] == results[1]
