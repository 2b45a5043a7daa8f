"""The single Robot env's whole step as one compiled call (numba), for ``RobotEnv.step``.

What the contract's step does between the agent's action and the returned numbers, for the
Robot with no correcting person or with the eq. M6 teacher (``Task.m6_drawn``): the action
clipped and scaled to u_R, the person's correction from their draws (``robot_m6_drawn``), the
clipped move f(x, u_H, u_R) and its IK solve (``ik_kernel._solve_recover``), the actuators'
``ctrl``, φ of the state reached, the reward θ*·φ and the observation's float32 numbers, each
with the IEEE operations of the plain path in its order, so the same bits. Numba's dispatch
costs per argument: the arm's MuJoCo views and constants go in as one array of addresses
(``arm_pointers``), rebuilt as arrays inside (``numba.carray``).

The reward is numpy's ``phi @ theta`` of two numbers: OpenBLAS's ``ddot`` rounds the first
product and fuses the second into it. ``reward_agrees`` checks that against this process's
numpy first; under another BLAS the contract's step runs. This module imports numba: import
it only when ``strol_gym.compiled.use_fast()``.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numba import carray, types

from strol_gym.envs.panda.ik_kernel import (
    KIN,
    _arm_args,
    _call_md,
    _fma,
    _jit,
    _solve_recover,
    intrinsic,
    reference,
    solver,
)
from strol_gym.envs.panda.model import N_ARM, Q_HOME
from strol_gym.pcg64_fill import fill_row, mixture, normals
from strol_gym.tasks.m6_kernels import robot_m6_drawn

OBS, OUT = 10, 20
"""Sizes of a step's float32 observation (state, u_H, θ̂, φ) and float64 numbers (below)."""
X, TARGET, PHI, U_H, U_R, THETA_STAR, THETA_HAT, REWARD, IK_ERROR = 0, 3, 6, 8, 11, 14, 16, 18, 19
"""Where ``robot_step`` writes each number of its float64 output (x', the IK target, φ, u_H,
u_R, θ*, θ̂, the reward, the IK's error)."""
PLACED = PHI + 2
"""The size of ``robot_place``'s float64 output (x0 reached, φ)."""
OK, BAD_ACTION, BAD_CORRECTION = 0, 1, 2
"""``robot_step``'s answers: done; a NaN or infinite action or correction (nothing moved)."""


def _pointer_at(kind: Any) -> Any:
    """An intrinsic turning an address (an integer) into a pointer to ``kind``, for
    ``numba.carray``."""
    ptr = types.CPointer(kind)

    @intrinsic
    def at(typingctx, address):
        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(ptr))

        return ptr(types.intp), codegen

    return at


_f64_at = _pointer_at(types.float64)
_intp_at = _pointer_at(types.intp)


_FIELDS = 29
"""The length of ``arm_pointers``: (model, data, site), 14 addresses, nv, the seed table's
shape, MuJoCo's C functions (``ik_kernel._FP``) and the IK's iterations."""


def arm_pointers(ik: Any, fp: np.ndarray, iters: int) -> tuple[np.ndarray, tuple] | None:
    """The arm's MuJoCo views and constants (``ik_kernel._arm_args``), MuJoCo's C functions
    ``fp`` and the IK's ``iters`` as one intp array, with the arrays it points into (keep them
    alive); None where one of them is not C-contiguous (then the contract's step runs)."""
    (ptr, xpos, xmat, q, jp, jr, w9, orient), (consts, table, grid, top), (limits, no_ref) = (
        _arm_args(ik)
    )
    ctrl = ik.data.ctrl[:N_ARM]
    arrays = (xpos, xmat, q, jp, jr, w9, orient, consts, table, grid, limits, top, no_ref, ctrl)
    if not all(a.flags.c_contiguous for a in arrays) or top.dtype != np.intp or table.ndim != 4:
        return None
    if not all(a.dtype == np.float64 for a in arrays if a is not top):
        return None
    out = np.zeros(_FIELDS, dtype=np.intp)
    out[:3] = ptr
    out[3:17] = [a.ctypes.data for a in arrays]
    out[17] = jp.shape[1]
    out[18:22] = table.shape
    out[22:28] = fp
    out[28] = iters
    return out, arrays


def step_params(m6: np.ndarray, scale: np.ndarray, tol: float) -> np.ndarray:
    """``robot_step``'s ``prm``: ``RobotTask._m6_drawn``'s 21 numbers (α, σ, ε, plate, cup,
    the box's corners, the candidates' bound, a_max), the action's scale per axis, the IK's
    tolerance, then ``Q_HOME`` (``robot_place``'s posture where the seed table has none)."""
    return np.concatenate([m6, scale, [tol], Q_HOME]).astype(np.float64)


@_jit
def _features(x0, x1, x2, plate, cup):
    """``RobotTask._features_one``: (d0² + d2²) + d1² as its sum over the axes, d2² = +0."""
    d0, d1 = plate[0] - x0, plate[1] - x1
    e0, e1, e2 = cup[0] - x0, cup[1] - x1, cup[2] - x2
    return -math.sqrt(d0 * d0 + d1 * d1), -math.sqrt((e0 * e0 + e2 * e2) + e1 * e1)


@_jit
def _arm(ap):
    """The arrays behind ``arm_pointers``, in ``_solve_recover``'s order from ``xpos``."""
    nv = ap[17]
    return (
        carray(_f64_at(ap[3]), 3),
        carray(_f64_at(ap[4]), 9),
        carray(_f64_at(ap[5]), N_ARM),
        carray(_f64_at(ap[6]), (3, nv)),
        carray(_f64_at(ap[7]), (3, nv)),
        carray(_f64_at(ap[8]), nv),
        carray(_f64_at(ap[9]), (3, 9)),
        carray(_f64_at(ap[10]), 7),
        carray(_f64_at(ap[11]), (ap[18], ap[19], ap[20], ap[21])),
        carray(_f64_at(ap[12]), (2, 3)),
        carray(_intp_at(ap[14]), 3),
        carray(_f64_at(ap[13]), (2, N_ARM)),
        carray(_f64_at(ap[15]), N_ARM),
        carray(_f64_at(ap[16]), N_ARM),
    )


@_jit
def _reached(ap, prm, target, iters, obs, out):
    """The IK solve towards ``target`` (``_solve_recover``), ``ctrl`` set to the joints, the
    end effector (task frame) at ``out[X]``, its φ at ``out[PHI]`` and their float32 copies
    into ``obs`` (state at 0, φ at 8); returns the IK's error."""
    xpos, xmat, q, jp, jr, w9, orient, consts, seeds, grid, top, limits, no_ref, ctrl = _arm(ap)
    err = _solve_recover(
        ap[22:28], ap[:3], xpos, xmat, q, jp, jr, w9, orient, target, iters, prm[24], consts,
        seeds, grid, top, limits, no_ref,
    )  # fmt: skip
    for j in range(N_ARM):
        ctrl[j] = q[j]
    for i in range(3):
        out[X + i] = xpos[i] - consts[i]
    phi = _features(out[X], out[X + 1], out[X + 2], prm[3:6], prm[6:9])
    out[PHI], out[PHI + 1] = phi[0], phi[1]
    for i in range(3):
        obs[i] = np.float32(out[X + i])
    for i in range(2):
        obs[8 + i] = np.float32(out[PHI + i])
    return err


@_jit
def robot_draws(states, modes, jitter, idx, z, theta, unit):
    """A reset's draws from the generator at ``states[0]``: θ* from the mixture prior (its
    index and jitter as ``MixturePrior.sample_each``, then modes[i] + jitter·z into ``theta``),
    then the start's uniforms ``unit`` (3,) (``rng.random(3)``); ``idx`` (1,), ``z`` (1, d)
    scratch."""
    mixture(states, modes.shape[0], idx, z)
    for j in range(theta.shape[0]):
        theta[j] = modes[idx[0], j] + jitter * z[0, j]
    fill_row(states[0], unit)


@_jit
def robot_place(ap, prm, unit, theta_hat, obs, out):
    """A reset's start: x0 = low + (high − low)·U in the box from the uniform draws ``unit`` (3,)
    (``RobotTask._in_box``), the arm put there as ``RobotEnv.move_to`` does (the seed table's
    posture nearest x0, else ``Q_HOME``, then 2 x the IK's iterations), then as ``_reached``;
    ``obs``' u_H zeros, θ̂ as float32."""
    arm = _arm(ap)
    q, seeds, grid, top, no_ref = arm[2], arm[8], arm[9], arm[10], arm[12]
    lo, hi = prm[9:12], prm[12:15]
    x0 = np.empty(3)
    for i in range(3):
        x0[i] = lo[i] + (hi[i] - lo[i]) * unit[i]
    ref, has_ref = reference(x0, seeds, grid[0], grid[1], top, no_ref)
    for j in range(N_ARM):
        q[j] = ref[j] if has_ref else prm[25 + j]
    _call_md(ap[22 + KIN], ap[0], ap[1])
    _reached(ap, prm, x0, 2 * ap[28], obs, out)
    for i in range(3):
        obs[3 + i] = np.float32(0.0)
    for i in range(2):
        obs[6 + i] = np.float32(theta_hat[i])


@_jit
def robot_step(ap, prm, x, action, theta_hat, theta_star, units, noise, obs, out, mode, state):
    """One env step: ``mode`` 0 no correction (u_H = 0), 1 the eq. M6 teacher's from its draws
    ``units`` (1, K, 3) and ``noise`` (1, 3), drawn here first (after the action's check, as
    ``Generator.random(out=units)`` then ``standard_normal(out=noise)``) from the generator
    whose ``ctypes.state_address`` is ``state`` unless that is 0. ``ap``: ``arm_pointers``;
    ``prm``: ``step_params``. Writes ``obs`` (float32: x', u_H, θ̂, φ) and ``out`` (float64, at
    ``X``, ``TARGET`` ...); returns ``OK`` or, having moved nothing, ``BAD_ACTION`` (nothing
    drawn) / ``BAD_CORRECTION``."""
    lo, hi, scale = prm[9:12], prm[12:15], prm[21:24]
    for i in range(3):  # as ``CorrectionEnv._robot_action``
        if not math.isfinite(action[i]):
            return BAD_ACTION
    if mode == 1 and state != 0:
        fill_row(state, units.reshape(units.size))
        normals(state, noise.reshape(noise.size))
    u_r, u_h = out[U_R : U_R + 3], out[U_H : U_H + 3]
    for i in range(3):
        v = float(action[i])
        v = 1.0 if v > 1.0 else (-1.0 if v < -1.0 else v)
        u_r[i] = v * scale[i]
    if mode == 1:  # ``NominalModel.drawn_corrections`` of one person
        rows, th = np.empty((3, 1, 3)), np.empty((2, 1, 2))  # x, u_R, u_H; θ̂, θ*
        for i in range(3):
            rows[0, 0, i], rows[1, 0, i] = x[i], u_r[i]
        for i in range(2):
            th[0, 0, i], th[1, 0, i] = theta_hat[i], theta_star[i]
        robot_m6_drawn(rows[0], rows[1], th[0], th[1], units, noise, prm, rows[2])
        for i in range(3):
            u_h[i] = rows[2, 0, i]
            if not math.isfinite(u_h[i]):
                return BAD_CORRECTION
    else:
        for i in range(3):
            u_h[i] = 0.0
    target = out[TARGET : TARGET + 3]
    for i in range(3):  # as ``ik_kernel._moved_recover``: min(max((x + u_R) + u_H, low), high)
        v = x[i] + u_r[i] + u_h[i]
        v = lo[i] if v < lo[i] else v
        target[i] = hi[i] if v > hi[i] else v
    out[IK_ERROR] = _reached(ap, prm, target, ap[28], obs, out)
    out[REWARD] = _fma(out[PHI + 1], theta_star[1], out[PHI] * theta_star[0])  # phi @ θ*
    for i in range(2):
        out[THETA_STAR + i] = theta_star[i]
        out[THETA_HAT + i] = theta_hat[i]
        obs[6 + i] = np.float32(theta_hat[i])
    for i in range(3):
        obs[3 + i] = np.float32(u_h[i])
    return OK


@_jit
def _dots(p, t, out):
    for i in range(p.shape[0]):
        out[i] = _fma(p[i, 1], t[i, 1], p[i, 0] * t[i, 0])


@functools.cache
def reward_agrees(cases: int = 400) -> bool:
    """Whether ``robot_step``'s reward equals numpy's ``phi @ theta`` (this process's BLAS)
    bit for bit on random pairs of two numbers, and MuJoCo's kernel runs here
    (``ik_kernel.solver``)."""
    if solver() is None:
        return False
    rng = np.random.default_rng(0)
    p = rng.standard_normal((cases, 2)) * rng.uniform(0, 2, (cases, 1))
    t = rng.standard_normal((cases, 2))
    got = np.empty(cases)
    _dots(p, t, got)
    want = np.array([a @ b for a, b in zip(p, t, strict=True)])
    return got.tobytes() == want.tobytes()
