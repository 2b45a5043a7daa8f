"""StROL-Study-v2's control step in one compiled call (numba): its chunks of the tracking law
(``chunk.chunk``), the joint brake's own physics steps (``ImpedanceController._braked_steps``,
``_brake``, the reflexes' checks) and the contact note (``_note_contact``, reading ``mjData``'s
contacts by address: ``data_layout``), the Jacobian between chunks and the positions' refresh
at the end: Python paid its own overhead around each of these, twice a control step.

Every sum is the plain path's: numpy's own BLAS and LAPACK calls by address (``chunk``), the
element-wise rest in the plain path's order (no fast-math). What it cannot do it hands back:
a reflex trips (``TRIP``: the env's ``_trip``), a singular brake solve (``SINGULAR``).

This module imports numba: import it only when ``strol_gym.compiled.use_fast()``.
"""

from __future__ import annotations

import math

import numpy as np

from strol_gym.envs.panda.ik_kernel import _call_jac
from strol_gym.envs.study.admittance import SETTLED
from strol_gym.envs.study.chunk import (
    BRAKE_ALL,
    COM_POS,
    CONTACT_AT,
    CONTACT_SIZE,
    DATA,
    FORWARD_SKIP,
    GEMM,
    GEMV,
    GEOM1_AT,
    GEOM2_AT,
    GESV,
    INTEGRAL,
    JAC_SITE,
    KINEMATICS,
    MODEL,
    NCON_AT,
    STEP,
    STEP1,
    STEP2,
    TORQUES,
    _call_md,
    _call_skip,
    _jit,
    _load_i32,
    _load_ptr,
    _ptr,
    chunk,
    feeds,
    gemm,
    gemv,
    solve,
)
from strol_gym.envs.study.scene import HOLD

TRIP, SINGULAR = 1, 2
"""``control_step``'s answers besides 0 (the step done): the reflex trips (the brakes lock the
arm), a brake's held joints' block of M⁻¹ is singular (the plain path's solve raises)."""
RERUN, JOINT_ROOM, CUP, STAGE_VEL, TOUCHED, AT_CHUNK, ACC, FEED = range(8)
"""``ints``' entries: the counterfactual's rerun (1/0), the version's ``joint_room``, the cup's
geom, MuJoCo's ``mjSTAGE_VEL``; what the step writes: the cup touched an object (1/0), the
chunk it stopped in; then whether Λ a_sp and the constant torques are due (``chunk.feeds``)."""
BRAKE_CAP, EXACT_CAP, REFLEX_CAP, TORQUE_CAP, COMP, LOW, HIGH, TWISTS, WATCH_CAP = range(9)
"""``caps``' rows: ``BRAKE_FROM``, ``EXACT_FROM`` and ``SPEED_REFLEX`` of the speed limits, the
torque limits, the joints' damping cancelled (``JOINT_COMP``), the position limits, the
twisting joints (1.0/0.0), ``WATCH_FROM`` of the speed limits."""
VAR = 19
"""``control_step``'s ``var`` per chunk: the admittance's offset (3), ``back``, whether its
wrench feed and damping torques apply (1.0/0.0), the feed (6), the damping torques (7)."""
N = 7


@_jit
def ahead(fp, m_inv, tau, tau_last, qd, qacc, h, out):
    """``_ahead(tau, 1)`` into ``out``: qd + h (q̈ + M⁻¹ (tau − tau_last))."""
    delta = np.empty(N)
    for j in range(N):
        delta[j] = tau[j] - tau_last[j]
    acc = np.zeros(N)
    gemv(fp[GEMV], m_inv, delta, acc)
    for j in range(N):
        out[j] = qd[j] + h * (qacc[j] + acc[j])


@_jit
def brake(fp, m_inv, base, tau_last, qd, qacc, h, caps, out):
    """``_brake(base, BRAKE_FROM's caps, the torque limits)`` into ``out``; False where a held
    block of M⁻¹ is singular."""
    cap, tlim = caps[BRAKE_CAP], caps[TORQUE_CAP]
    free, nxt = np.empty(N), np.empty(N)
    ahead(fp, m_inv, base, tau_last, qd, qacc, h, free)
    for j in range(N):
        out[j] = base[j]
    held, new = np.empty(N, np.int64), np.empty(N, np.int64)
    n_held = 0
    for _ in range(N):
        if n_held:
            ahead(fp, m_inv, out, tau_last, qd, qacc, h, nxt)
        else:
            nxt[:] = free
        n_new = 0
        for j in range(N):
            if abs(nxt[j]) > cap[j]:
                seen = False
                for k in range(n_held):
                    seen = seen or held[k] == j
                if not seen:
                    new[n_new] = j
                    n_new += 1
        if n_new == 0:
            break
        for k in range(n_new):
            held[n_held] = new[k]
            n_held += 1
        block, want = np.empty((n_held, n_held)), np.empty((n_held, 1))
        for r in range(n_held):
            j = held[r]
            want[r, 0] = (math.copysign(cap[j], free[j]) - free[j]) / h
            for c in range(n_held):
                block[r, c] = m_inv[j, held[c]]
        info, cut = solve(fp[GESV], block, want)
        if info != 0:
            return False
        for j in range(N):
            out[j] = base[j]
        for r in range(n_held):
            j = held[r]
            v = base[j] + cut[r, 0]
            v = v if v > -tlim[j] else -tlim[j]  # Python's max(-lim, v), then min(lim, v)
            out[j] = v if v < tlim[j] else tlim[j]
    return True


@_jit
def touches(fp, cup, objects):
    """Whether a contact of the cup's geom with one of ``objects`` is in ``mjData`` now."""
    d = fp[DATA]
    n = _load_i32(d + fp[NCON_AT])
    if n == 0:
        return False
    first = _load_ptr(d + fp[CONTACT_AT])
    for i in range(n):
        at = first + i * fp[CONTACT_SIZE]
        a, b = _load_i32(at + fp[GEOM1_AT]), _load_i32(at + fp[GEOM2_AT])
        for g in objects:
            if (a == cup and b == g) or (b == cup and a == g):
                return True
    return False


@_jit
def at_limit(q, qd, caps, reach):
    """``_at_limit``: a twisting joint within ``reach`` of a position limit, moving to it."""
    for j in range(N):
        if caps[TWISTS, j] != 0.0:
            if (q[j] > caps[HIGH, j] - reach and qd[j] > 0.0) or (
                q[j] < caps[LOW, j] + reach and qd[j] < 0.0
            ):
                return True
    return False


@_jit
def braked_steps(fp, ints, steps, pushed, base0, tau_last, m_inv, caps, reach, q, qd, qacc,
                 ctrl, objects, h):  # fmt: skip
    """``_braked_steps(pushed, steps)`` with ``tau_last`` (the last step's torques, updated in
    place) and the contact note in ``ints``; 0, ``TRIP`` or ``SINGULAR``."""
    m, d = fp[MODEL], fp[DATA]
    rerun = ints[RERUN] != 0
    exact, reflex, tlim = caps[EXACT_CAP], caps[REFLEX_CAP], caps[TORQUE_CAP]
    base, nxt, tau, braked = np.empty(N), np.empty(N), np.empty(N), np.empty(N)
    for _ in range(steps):
        for j in range(N):
            base[j] = base0[j] + caps[COMP, j] * qd[j]
        ahead(fp, m_inv, base, tau_last, qd, qacc, h, nxt)
        near = False
        for j in range(N):
            near = near or abs(qd[j]) > exact[j] or abs(nxt[j]) > exact[j]
        if near:  # the brake at this state's acceleration (mj_step1 + mj_step2 = mj_step)
            _call_md(fp[STEP1], m, d)
            tau[:] = base
            for look in range(3):
                for j in range(N):
                    ctrl[j] = tau_last[j] = tau[j]
                _call_skip(fp[FORWARD_SKIP], m, d, np.int32(ints[STAGE_VEL]), np.int32(0))
                if look == 0 and pushed and not rerun:  # ``_too_fast``
                    for j in range(N):
                        if abs(qd[j] + h * qacc[j]) > reflex[j]:
                            return TRIP
                if not brake(fp, m_inv, tau, tau_last, qd, qacc, h, caps, braked):
                    return SINGULAR
                same = True
                for j in range(N):
                    same = same and braked[j] == tau_last[j]
                tau[:] = braked
                if same:
                    break
            for j in range(N):
                ctrl[j] = tau[j]
            _call_md(fp[STEP2], m, d)
        else:
            for j in range(N):
                ctrl[j] = base[j]
            _call_md(fp[STEP], m, d)
        for j in range(N):
            tau_last[j] = ctrl[j]
        if ints[TOUCHED] == 0 and touches(fp, ints[CUP], objects):
            ints[TOUCHED] = 1
        if rerun:
            continue
        if pushed and ints[JOINT_ROOM] != 0 and at_limit(q, qd, caps, reach):
            return TRIP
        for j in range(N):  # the speed reflex
            s, a, r = qd[j], qacc[j], reflex[j]
            if abs(s + h * a) <= r:
                continue
            push = -math.copysign(tlim[j], s) - tau_last[j]
            if abs(s + h * (a + m_inv[j, j] * push)) > r:
                return TRIP
    return 0


@_jit
def control_step(fp, par, var, targets, kmat, gain, m_inv, jac, caps, reach, ints, q, qd, qacc,
                 ctrl, xpos, xmat, objects, site, lam, jt_damp, dyn_inv, pull_home, joint_damping,
                 v_sp, v_prev, inv_dt):  # fmt: skip
    """The control step's feedforward terms where due (``chunk.feeds`` into ``par``: Λ a_sp,
    the constant torques), its chunks (``var``'s rows; ``targets``: each chunk's target
    rotation) from the first chunk's law on (its Jacobian and the model refresh are the
    caller's), then ``mj_kinematics`` and ``mj_comPos``. ``par`` as ``chunk.chunk``'s, its
    last torques (35:42) kept up to date. Returns 0, or ``TRIP``/``SINGULAR`` with the chunk
    in ``ints`` (nothing after it run)."""
    m, d = fp[MODEL], fp[DATA]
    acc, feed = ints[ACC] != 0, ints[FEED] != 0
    if acc or feed:
        acc_ff, const = feeds(fp, lam, jt_damp, dyn_inv, pull_home, joint_damping, v_sp, v_prev,
                              inv_dt, acc, feed)  # fmt: skip
        if acc:
            par[22:28] = acc_ff
        if feed:
            par[28:35] = const
    h = par[17]
    tau_last = par[35:42]
    base0 = np.empty(N)
    for i in range(var.shape[0]):
        if i:
            at = _ptr(jac)
            _call_jac(fp[JAC_SITE], m, d, at, at + 8 * 3 * jac.shape[1], np.int32(site))
        v = var[i]
        par[3], par[4], par[5], par[12] = v[0], v[1], v[2], v[3]
        par[20], par[21] = v[4], v[5]
        par[42:48] = v[6:12]
        par[48:55] = v[12:19]
        left = chunk(fp, par, targets[i], kmat, gain, m_inv, jac, caps[WATCH_CAP],
                     caps[BRAKE_CAP], q, qd, qacc, ctrl, xpos, xmat)  # fmt: skip
        code = 0
        if left == BRAKE_ALL:
            base0[:] = ctrl[:N]
            code = braked_steps(fp, ints, HOLD, par[19] == 0.0, base0, tau_last, m_inv, caps,
                                reach, q, qd, qacc, ctrl, objects, h)  # fmt: skip
        else:
            tau_last[:] = par[TORQUES : TORQUES + N]
            if ints[TOUCHED] == 0 and touches(fp, ints[CUP], objects):
                ints[TOUCHED] = 1
            if left:
                base0[:] = ctrl[:N]
                code = braked_steps(fp, ints, left, False, base0, tau_last, m_inv, caps, reach,
                                    q, qd, qacc, ctrl, objects, h)  # fmt: skip
        if code:
            ints[AT_CHUNK] = i
            return code
    _call_md(fp[KINEMATICS], m, d)
    _call_md(fp[COM_POS], m, d)
    return 0


__all__ = ["INTEGRAL", "SINGULAR", "TRIP", "VAR", "control_step"]


@_jit
def admitted(fp, coef, state, rest, wext, lam, jt_damp, dyn_inv, sp_r, dt_i, control_dt, var,
             targets, states):  # fmt: skip
    """``ImpedanceController._admitted`` (``Admittance.step``, ``_cap_speed``, ``rotation``,
    the products by numpy's BLAS) into ``control_step``'s ``var`` and ``targets``, and each
    chunk's admittance state after it into ``states`` (its 13th entry 1.0 where it is REST).
    ``coef``: the admittance's Φ (6) and 1/M (6), then the joints' speed caps (7); ``state``,
    ``rest``: the admittance's state before the step and whether it is REST."""
    p00, p01, p10, p11, c0, c1 = coef[0], coef[1], coef[2], coef[3], coef[4], coef[5]
    pushed = False
    for k in range(6):
        if wext[k] != 0.0:
            pushed = True
    s0, s1 = state.copy(), np.zeros(12)
    inv = 1.0 / dt_i
    rot, acc, vel = np.zeros((3, 3)), np.zeros(6), np.zeros(6)
    feed, damp, need = np.zeros(6), np.zeros(N), np.zeros(N)
    for i in range(var.shape[0]):
        var[i, :] = 0.0
        var[i, 3] = control_dt - i * dt_i
        if rest and not pushed:  # the admittance does not act: the setpoint's rotation
            targets[i] = sp_r
            states[i, :12] = s0
            states[i, 12] = 1.0
            continue
        top = 0.0
        for k in range(6):
            u = wext[k] * coef[6 + k]
            s1[k] = p00 * s0[k] + p01 * s0[6 + k] + c0 * u
            s1[6 + k] = p10 * s0[k] + p11 * s0[6 + k] + c1 * u
        for k in range(12):
            a = abs(s1[k])
            if k == 0 or a > top:
                top = a
        rest = not pushed and top < SETTLED
        if rest:
            s1[:] = 0.0
        gemv(fp[GEMV], dyn_inv, s1[6:].copy(), need)
        over = 0.0
        for j in range(N):
            a = abs(need[j]) / coef[12 + j]
            if j == 0 or a > over:
                over = a
        if not over <= 1.0:
            for k in range(6, 12):
                s1[k] = s1[k] / over
        ox, oy, oz = 0.5 * (s0[0] + s1[0]), 0.5 * (s0[1] + s1[1]), 0.5 * (s0[2] + s1[2])
        rx, ry, rz = 0.5 * (s0[3] + s1[3]), 0.5 * (s0[4] + s1[4]), 0.5 * (s0[5] + s1[5])
        _rotation(rx, ry, rz, rot)
        out = np.zeros((3, 3))
        gemm(fp[GEMM], rot, sp_r, out)
        targets[i] = out
        for k in range(6):
            acc[k] = (s1[6 + k] - s0[6 + k]) * inv
            vel[k] = (s1[k] - s0[k]) * inv
        gemv(fp[GEMV], lam, acc, feed)
        gemv(fp[GEMV], jt_damp, vel, damp)
        var[i, 0], var[i, 1], var[i, 2], var[i, 4], var[i, 5] = ox, oy, oz, 1.0, 1.0
        for k in range(6):
            var[i, 6 + k] = feed[k] - wext[k]
        var[i, 12 : 12 + N] = damp
        states[i, :12] = s1
        states[i, 12] = 1.0 if rest else 0.0
        s0[:] = s1


@_jit
def _rotation(rx, ry, rz, out):
    """``admittance.rotation`` into ``out`` (Rodrigues, its operations in order)."""
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    out[:] = 0.0
    if angle < 1e-12:
        out[0, 0] = out[1, 1] = out[2, 2] = 1.0
        return
    x, y, z = rx / angle, ry / angle, rz / angle
    s, c = math.sin(angle), math.cos(angle)
    t = 1.0 - c
    out[0, 0], out[0, 1], out[0, 2] = c + t * x * x, t * x * y - s * z, t * x * z + s * y
    out[1, 0], out[1, 1], out[1, 2] = t * x * y + s * z, c + t * y * y, t * y * z - s * x
    out[2, 0], out[2, 1], out[2, 2] = t * x * z - s * y, t * y * z + s * x, c + t * z * z
