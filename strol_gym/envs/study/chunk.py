"""StROL-Study-v2's control chunk as one compiled call (numba) that calls MuJoCo and numpy's
BLAS itself: the tracking law's torques and the joint brake's watched physics steps
(``ImpedanceController._simulate_v1``, ``_step_braked``, ``_watched_steps``) between two
Python calls, where Python paid its own overhead around every one of ``HOLD`` ``mj_step``\\ s.

The small products (K e, G [q; q̇], Jᵀ w, M⁻¹ Δτ, R_target R_cupᵀ) are the very calls
``ndarray.dot`` makes: numpy's bundled OpenBLAS ``cblas_dgemv``/``cblas_dgemm``, reached
through their addresses with numpy's arguments, so they sum in OpenBLAS's order under any of
its core types; the rest is the plain path's IEEE operations in its order (no fast-math).
``functions()`` finds the addresses once per process and checks the products against numpy on
random inputs (``_agrees``): elsewhere (another BLAS, another platform) the plain path runs.

This module imports numba: import it only when ``strol_gym.compiled.use_fast()``.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
from typing import Any

import numpy as np
from llvmlite import ir
from numba import njit, types

from strol_gym.envs.panda.ik_kernel import (
    _addresses,
    _c_function,
    _call_md,
    intrinsic,
)
from strol_gym.envs.study.data_layout import contact_layout
from strol_gym.envs.study.scene import HOLD

ROW_MAJOR, NO_TRANS, TRANS = 101, 111, 112
"""CBLAS's ``CblasRowMajor``, ``CblasNoTrans`` and ``CblasTrans``."""
(STEP, GEMV, GEMM, FULL_M, GESV, STEP1, STEP2, FORWARD_SKIP, JAC_SITE, KINEMATICS, COM_POS,
 NCON_AT, CONTACT_AT, CONTACT_SIZE, GEOM1_AT, GEOM2_AT, MODEL, DATA) = range(18)  # fmt: skip
"""Where ``functions()`` puts each C function's address and ``mjData``'s contact layout
(``data_layout.contact_layout``), then where the controller puts the model's and the data's."""
_MUJOCO = (
    *("mj_step", "mj_fullM", "mj_step1", "mj_step2", "mj_forwardSkip", "mj_jacSite"),
    *("mj_kinematics", "mj_comPos"),
)
BRAKE_ALL = -1
"""``chunk``'s answer when the chunk's physics is the brake's from its first step."""

_jit: Any = njit(cache=True, nogil=True)  # checked by numba, not mypy
_p, _i, _f = types.intp, types.int32, types.float64


@intrinsic
def _call_skip(typingctx, address, m, d, skipstage, skipsensor):
    """mj_forwardSkip(m, d, skipstage, skipsensor) at ``address``."""
    return _c_function(None, (_p, _p, _i, _i))


@intrinsic
def _load_i32(typingctx, address):
    """The C ``int`` at ``address``."""

    def codegen(context, builder, signature, llargs):
        return builder.load(builder.inttoptr(llargs[0], ir.IntType(32).as_pointer()))

    return types.int32(types.intp), codegen


@intrinsic
def _load_ptr(typingctx, address):
    """The pointer at ``address``, as an integer."""

    def codegen(context, builder, signature, llargs):
        return builder.load(builder.inttoptr(llargs[0], ir.IntType(64).as_pointer()))

    return types.intp(types.intp), codegen


@intrinsic
def _call_full_m(typingctx, address, m, d, dst):
    """mj_fullM(m, d, dst) at ``address``."""
    return _c_function(None, (_p, _p, _p))


@intrinsic
def _call_gesv(typingctx, address, n, nrhs, a, lda, ipiv, b, ldb, info):
    """LAPACK's dgesv (ILP64, Fortran: every argument a pointer) at ``address``."""
    return _c_function(None, (_p, _p, _p, _p, _p, _p, _p, _p))


@intrinsic
def _call_gemv(typingctx, address, order, trans, m, n, alpha, a, lda, x, incx, beta, y, incy):
    """cblas_dgemv (ILP64) at ``address``."""
    return _c_function(None, (_i, _i, _p, _p, _f, _p, _p, _p, _p, _f, _p, _p))


@intrinsic
def _call_gemm(typingctx, address, order, ta, tb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc):
    """cblas_dgemm (ILP64) at ``address``."""
    return _c_function(None, (_i, _i, _i, _p, _p, _p, _f, _p, _p, _p, _p, _f, _p, _p))


@_jit
def _ptr(a):
    return np.intp(a.ctypes.data)


@_jit
def gemv(fp, a, x, out, trans=NO_TRANS):
    """out = a x as ``a.dot(x)`` computes it, or with ``trans`` = ``TRANS`` out = x a as
    ``x.dot(a)`` does (a C-contiguous, x contiguous)."""
    m, n = a.shape
    _call_gemv(
        fp, np.int32(ROW_MAJOR), np.int32(trans), m, n, 1.0, _ptr(a), n, _ptr(x), 1, 0.0,
        _ptr(out), 1,
    )  # fmt: skip


@_jit
def gemm_bt(fp, a, b, out):
    """out = a bᵀ as ``a.dot(b.T)`` computes it (a, b C-contiguous: bᵀ is Fortran-ordered)."""
    rows, inner = a.shape
    _call_gemm(
        fp, np.int32(ROW_MAJOR), np.int32(NO_TRANS), np.int32(TRANS), rows, b.shape[0], inner,
        1.0, _ptr(a), inner, _ptr(b), inner, 0.0, _ptr(out), b.shape[0],
    )  # fmt: skip


@_jit
def gemm(fp, a, b, out):
    """out = a b as ``a.dot(b)`` computes it (a, b C-contiguous)."""
    rows, inner = a.shape
    cols = b.shape[1]
    _call_gemm(
        fp, np.int32(ROW_MAJOR), np.int32(NO_TRANS), np.int32(NO_TRANS), rows, cols, inner,
        1.0, _ptr(a), inner, _ptr(b), cols, 0.0, _ptr(out), cols,
    )  # fmt: skip


@_jit
def solve(fp, a, b):
    """``np.linalg.solve(a, b)`` (b None: ``np.linalg.inv(a)``) as numpy computes it: LAPACK's
    dgesv on column-major copies; None where a is singular (numpy raises)."""
    n = a.shape[0]
    nrhs = n if b is None else b.shape[1]
    a_f, b_f = np.zeros(n * n), np.zeros(n * nrhs)
    for i in range(n):
        for j in range(n):
            a_f[i + j * n] = a[i, j]
        for j in range(nrhs):
            if b is None:
                b_f[i + j * n] = 1.0 if i == j else 0.0
            else:
                b_f[i + j * n] = b[i, j]
    ints = np.array([n, nrhs, n, n, 0], dtype=np.int64)
    ipiv = np.zeros(n, dtype=np.int64)
    at = _ptr(ints)
    _call_gesv(fp, at, at + 8, _ptr(a_f), at + 16, _ptr(ipiv), _ptr(b_f), at + 24, at + 32)
    out = np.zeros((n, nrhs))
    for i in range(n):
        for j in range(nrhs):
            out[i, j] = b_f[i + j * n]
    return ints[4], out


PAR = 68
"""``chunk``'s ``par``: spx, spy, spz, ox, oy, oz, vx, vy, vz, wx, wy, wz (the setpoint, the
admittance's offset, the setpoint's velocity), back, gp, gr, ip, ir, the timestep, then flags
(1.0/0.0: integrate, step, feed, damp), then Λ a_sp (6), the constant torques (7), the last
step's torques (7), the admittance's wrench feed (6) and its damping torques (7); then what
the chunk updates: the integral (6, when it integrates) and the torques it set (7)."""
INTEGRAL, TORQUES = 55, 61
"""Where ``par`` holds the integral and the chunk's torques."""


@_jit
def chunk(fp, par, target_r, kmat, gain, m_inv, jac, watch_cap, brake_cap, q, qd, qacc, ctrl,
          xpos, xmat):  # fmt: skip
    """One control chunk of v2's tracking law (``ImpedanceController._simulate_v1``, the
    ``track_bandwidth`` branch) and, unless ``par`` says not to step (a person pushes), the
    brake's first checks and its watched physics steps (``_step_braked``, ``_watched_steps``).
    Returns 0 (the chunk's steps all taken), ``BRAKE_ALL`` (none taken: the brake's chunk
    follows) or the steps a watched step's look-ahead left to the brake.

    ``fp``: ``functions()``' addresses, then the model's and the data's; ``par``: see ``PAR``."""
    step_fn, gemv_fn, gemm_fn, m, d = fp[STEP], fp[GEMV], fp[GEMM], fp[MODEL], fp[DATA]
    rot = np.zeros((3, 3))  # BLAS's outputs zeroed first, as numpy's
    gemm_bt(gemm_fn, target_r, xmat, rot)
    r01, r02, r10, r12, r20, r21 = rot[0, 1], rot[0, 2], rot[1, 0], rot[1, 2], rot[2, 0], rot[2, 1]
    back = par[12]
    x, y, z = xpos[0], xpos[1], xpos[2]
    e = np.empty(6)
    e[0] = par[0] + par[3] - par[6] * back - x
    e[1] = par[1] + par[4] - par[7] * back - y
    e[2] = par[2] + par[5] - par[8] * back - z
    e[3] = 0.5 * (r21 - r12) - par[9] * back
    e[4] = 0.5 * (r02 - r20) - par[10] * back
    e[5] = 0.5 * (r10 - r01) - par[11] * back
    ke = np.zeros(6)
    gemv(gemv_fn, kmat, e, ke)
    if par[18] != 0.0:
        for k in range(6):
            g, lim = (par[13], par[15]) if k < 3 else (par[14], par[16])
            v = par[INTEGRAL + k] + g * ke[k]
            v = v if v > -lim else -lim  # Python's max(-lim, v), then min(lim, v)
            par[INTEGRAL + k] = v if v < lim else lim
    w = np.empty(6)
    for k in range(6):
        w[k] = ke[k] + par[INTEGRAL + k] + par[22 + k]
        if par[20] != 0.0:
            w[k] = w[k] + par[42 + k]
    state = np.empty(14)
    for j in range(7):
        state[j] = q[j]
        state[7 + j] = qd[j]
    rest = np.zeros(7)
    gemv(gemv_fn, gain, state, rest)
    jtw = np.zeros(jac.shape[1])
    gemv(gemv_fn, jac, w, jtw, TRANS)
    for j in range(7):
        t = jtw[j] + par[28 + j] - rest[j]
        if par[21] != 0.0:
            t = t + par[48 + j]
        ctrl[j] = par[TORQUES + j] = t
    if par[19] == 0.0:
        return BRAKE_ALL
    for j in range(7):
        if abs(qd[j]) > watch_cap[j]:
            return BRAKE_ALL
    delta = np.empty(7)
    for j in range(7):
        delta[j] = par[TORQUES + j] - par[35 + j]
    extra = np.zeros(7)
    gemv(gemv_fn, m_inv, delta, extra)
    h = par[17]
    ahead = HOLD * h
    for j in range(7):
        if abs(qd[j] + ahead * (qacc[j] + extra[j])) > brake_cap[j]:
            return BRAKE_ALL
    for done in range(1, HOLD + 1):
        _call_md(step_fn, m, d)
        left = HOLD - done
        if left == 0:
            break
        drift = left * h
        for j in range(7):
            if abs(qd[j] + drift * qacc[j]) > brake_cap[j]:
                return left
    return 0


@_jit
def refresh(fp, mass, jac, q, q_home, jnt_range, twists, reg, band, k_null, d_null, k_limit,
            limit_band):  # fmt: skip
    """v2's model refresh (``ImpedanceController._model_terms``: the ``track_bandwidth``,
    ``joint_room`` and ``joint_brake`` branch, with ``_posture``): M (into ``mass``), then
    (ok, K, Λ, Jᵀ D, J̄ Λ... see the plain path) as numpy computes them; ok False where a
    matrix is singular (the plain path then raises as before)."""
    _call_full_m(fp[FULL_M], fp[MODEL], fp[DATA], _ptr(mass))
    n, rows = 7, jac.shape[0]
    ja, ja_t, m_arm = np.zeros((rows, n)), np.zeros((n, rows)), np.zeros((n, n))
    for i in range(rows):
        for j in range(n):
            ja[i, j] = ja_t[j, i] = jac[i, j]
    for i in range(n):
        for j in range(n):
            m_arm[i, j] = mass[i, j]
    info, m_inv_jt = solve(fp[GESV], m_arm, ja_t)
    jm = np.zeros((rows, rows))
    gemm(fp[GEMM], ja, m_inv_jt, jm)
    jm = jm + reg
    info_lam, lam = solve(fp[GESV], jm, None)
    kmat = (band * band) * lam
    jt_damp = np.zeros((n, rows))
    gemm(fp[GEMM], ja_t, (2.0 * band) * lam, jt_damp)
    lj = np.zeros((rows, n))
    gemm_bt(fp[GEMM], lam, m_inv_jt, lj)
    proj = np.zeros((n, n))
    gemm(fp[GEMM], ja_t, lj, proj)
    null = np.eye(n) - proj
    stiff, pull = np.zeros(n), np.zeros(n)
    for j in range(n):
        lo, hi = jnt_range[0, j], jnt_range[1, j]
        high, low = q[j] > hi - limit_band, q[j] < lo + limit_band
        edge = hi - limit_band if high else lo + limit_band
        inside = 1.0 if (high or low) and twists[j] else 0.0
        stiff[j] = k_null + k_limit * inside
        pull[j] = k_null * q_home[j] + k_limit * inside * edge
    pull_home = np.zeros(n)
    gemv(fp[GEMV], null, pull, pull_home)
    damped = np.zeros((n, n))
    gemm(fp[GEMM], jt_damp, ja, damped)
    gain = np.zeros((n, 2 * n))
    for i in range(n):
        for j in range(n):
            gain[i, j] = null[i, j] * stiff[j]
            gain[i, n + j] = damped[i, j] + d_null * null[i, j]
    dyn_inv = np.zeros((n, rows))
    gemm(fp[GEMM], m_inv_jt, lam, dyn_inv)
    info_m, m_inv = solve(fp[GESV], m_arm, None)
    ok = info == 0 and info_lam == 0 and info_m == 0
    return ok, kmat, lam, jt_damp, dyn_inv, gain, pull_home, m_inv


@_jit
def feeds(fp, lam, jt_damp, dyn_inv, pull_home, joint_damping, v_sp, v_prev, inv_dt, acc, feed):
    """``_model_terms``' feedforward terms as numpy computes them: where ``acc``, Λ a_sp with
    a_sp = (v_sp − v_prev) · inv_dt; where ``feed``, Jᵀ D v_sp + the joints' damping at J̄ v_sp
    + the null-space pull. Returns (Λ a_sp, the constant torques); an unasked one is zeros."""
    rows, n = lam.shape[0], jt_damp.shape[0]
    acc_ff, const = np.zeros(rows), np.zeros(n)
    if acc:
        a = (v_sp - v_prev) * inv_dt
        gemv(fp[GEMV], lam, a, acc_ff)
    if feed:
        damp, move = np.zeros(n), np.zeros(n)
        gemv(fp[GEMV], jt_damp, v_sp, damp)
        gemv(fp[GEMV], dyn_inv, v_sp, move)
        const = (damp + joint_damping * move) + pull_home
    return acc_ff, const


def _numpy_blas() -> ctypes.CDLL | None:
    """numpy's bundled OpenBLAS (a wheel's ``numpy.libs``), where numpy was built with it."""
    config: Any = np.show_config(mode="dicts")
    blas = config.get("Build Dependencies", {}).get("blas", {})
    if blas.get("name") != "scipy-openblas" or "USE64BITINT" not in str(blas):
        return None
    root = os.path.dirname(os.path.dirname(np.__file__))
    found = glob.glob(os.path.join(root, "numpy.libs", "libscipy_openblas64_*.so"))
    try:
        return ctypes.CDLL(found[0]) if len(found) == 1 else None
    except OSError:
        return None


@functools.cache
def functions() -> np.ndarray | None:
    """The C functions' addresses (``STEP``, ``GEMV``, ``GEMM``, ``FULL_M``, ``GESV``:
    MuJoCo's, then numpy's OpenBLAS's), or None: no such libraries or symbols, or products
    that do not give numpy's bits (``_agrees``)."""
    blas, mj, layout = _numpy_blas(), _addresses(_MUJOCO), contact_layout()
    names = ("scipy_cblas_dgemv64_", "scipy_cblas_dgemm64_", "scipy_dgesv_64_")
    if blas is None or mj is None or layout is None or not all(hasattr(blas, n) for n in names):
        return None
    gemv_fn, gemm_fn, gesv_fn = (
        ctypes.cast(getattr(blas, n), ctypes.c_void_p).value for n in names
    )
    fp = np.array([mj[0], gemv_fn, gemm_fn, mj[1], gesv_fn, *mj[2:], *layout], dtype=np.intp)
    return fp if _agrees(fp) else None


def _agrees(fp: np.ndarray, cases: int = 50) -> bool:
    """Whether the compiled products and solves equal numpy's bit for bit on random inputs of
    the controller's shapes (``OPENBLAS_CORETYPE`` and the library are this process's)."""
    rng = np.random.default_rng(0)
    same = True
    for _ in range(cases):
        for rows, cols in ((6, 6), (7, 7), (7, 14), (7, 6)):
            a, x, out = rng.standard_normal((rows, cols)), rng.standard_normal(cols), np.zeros(rows)
            gemv(fp[GEMV], a, x, out)
            same &= out.tobytes() == a.dot(x).tobytes()
        a, x, out = rng.standard_normal((6, 9)), rng.standard_normal(6), np.zeros(9)
        gemv(fp[GEMV], a, x, out, TRANS)
        same &= out.tobytes() == x.dot(a).tobytes()
        for rows, inner, cols in ((6, 7, 6), (7, 6, 6), (7, 6, 7), (3, 3, 3)):
            a, b = rng.standard_normal((rows, inner)), rng.standard_normal((inner, cols))
            prod = np.zeros((rows, cols))
            gemm(fp[GEMM], a, b, prod)
            same &= prod.tobytes() == a.dot(b).tobytes()
        for rows, inner, cols in ((6, 6, 7), (3, 3, 3)):
            a, b = rng.standard_normal((rows, inner)), rng.standard_normal((cols, inner))
            prod = np.zeros((rows, cols))
            gemm_bt(fp[GEMM], a, b, prod)
            same &= prod.tobytes() == a.dot(b.T).tobytes()
        m = rng.standard_normal((9, 9))
        m = m.dot(m.T) + np.eye(9)
        jt = rng.standard_normal((6, 9))[:, :7].T
        info, x = solve(fp[GESV], m[:7, :7].copy(), jt.copy())
        same &= info == 0 and x.tobytes() == np.linalg.solve(m[:7, :7], jt).tobytes()
        info, x = solve(fp[GESV], m[:6, :6].copy(), None)
        same &= info == 0 and x.tobytes() == np.linalg.inv(m[:6, :6]).tobytes()
        for k in range(1, 8):  # the brake's solves: a few held joints, one right-hand side
            held = rng.permutation(7)[:k]
            a, b = m[np.ix_(held, held)], rng.standard_normal(k)
            info, x = solve(fp[GESV], a, b.reshape(k, 1).copy())
            same &= info == 0 and x.ravel().tobytes() == np.linalg.solve(a, b).tobytes()
    return bool(same)


__all__ = ["BRAKE_ALL", "PAR", "chunk", "feeds", "functions", "refresh"]
