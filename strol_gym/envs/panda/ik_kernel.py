"""``PandaIK._solve`` as one compiled loop (numba) that calls MuJoCo's C functions itself.

The C-calling kernel: ``mj_kinematics``, ``mj_comPos``, ``mj_jacSite`` and MuJoCo's Cholesky and
Jᵀ products are the very calls of the plain path, reached through ``libmujoco``'s exported
symbols and the private ``MjModel._address`` / ``MjData._address`` of the Python binding. The
3x7 algebra that the plain path leaves to numpy's BLAS (OpenBLAS) is written out in the order
and with the fused multiply-adds of OpenBLAS's kernels (J Jᵀ: one fused multiply-add per joint,
in order; J s and the gripper-down term: ``dgemv_t``'s pairwise sums and fused tail), so every
iteration reaches the same bits. ``solver()`` checks that on random Jacobians against this
process's numpy first (``_agrees``): under another BLAS kernel the plain path runs.

The C functions' addresses are arguments, not constants compiled in (``_call``), so the kernel
is cached on disk like the others (``cache=True``): a process loads it instead of compiling.
This module imports numba: import it only when ``strol_gym.compiled.use_fast()``.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic as numba_intrinsic
from numba.extending import register_jitable

from strol_gym.envs.panda.ik_step import dls_solve, dls_step
from strol_gym.envs.panda.model import N_ARM

# An @intrinsic is called without its first parameter (numba passes the typing context), which
# numba's annotations do not say: typed as Any, the decorated calls are checked by numba alone.
intrinsic: Any = numba_intrinsic

_SYMBOLS = (
    "mj_kinematics",
    "mj_comPos",
    "mj_jacSite",
    "mju_cholFactor",
    "mju_cholSolve",
    "mju_mulMatTVec",
)
"""The C functions the kernel calls, in the order of its ``fp`` argument."""
KIN, COM, JAC, CHOL, SOLVE, MUL_T = range(len(_SYMBOLS))
_FP = np.zeros(len(_SYMBOLS), dtype=np.intp)
"""The C functions' addresses, once ``solver()`` has found them."""

_jit: Any = njit(cache=True, nogil=True)  # its functions are checked by numba, not mypy


@intrinsic
def _fma(typingctx, a, b, c):
    """a·b + c rounded once (LLVM's ``llvm.fma.f64``), as OpenBLAS's kernels compute."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(d, [d, d, d]), "llvm.fma.f64"
        )
        return builder.call(fn, args)

    return sig, codegen


def _c_function(ret: Any, params: tuple[Any, ...]) -> tuple[Any, Callable[..., Any]]:
    """The typing signature and code generator of a call to the C function whose address is
    the first argument, with C parameter types ``params`` (numba types) returning ``ret``."""

    def ll(t: Any) -> ir.Type:
        return ir.DoubleType() if t == types.float64 else ir.IntType(t.bitwidth)

    sig = (types.void if ret is None else ret)(types.intp, *params)

    def codegen(context, builder, signature, llargs):
        fnty = ir.FunctionType(ir.VoidType() if ret is None else ll(ret), [ll(p) for p in params])
        out = builder.call(builder.inttoptr(llargs[0], fnty.as_pointer()), llargs[1:])
        return context.get_dummy_value() if ret is None else out

    return sig, codegen


_p, _i, _f = types.intp, types.int32, types.float64


@intrinsic
def _call_md(typingctx, address, m, d):
    """mj_kinematics(m, d) or mj_comPos(m, d) at ``address``."""
    return _c_function(None, (_p, _p))


@intrinsic
def _call_jac(typingctx, address, m, d, jacp, jacr, site):
    """mj_jacSite(m, d, jacp, jacr, site) at ``address``."""
    return _c_function(None, (_p, _p, _p, _p, _i))


@intrinsic
def _call_chol(typingctx, address, mat, n, mindiag):
    """mju_cholFactor(mat, n, mindiag) at ``address``."""
    return _c_function(_i, (_p, _i, _f))


@intrinsic
def _call_solve(typingctx, address, res, mat, vec, n):
    """mju_cholSolve(res, mat, vec, n) at ``address``."""
    return _c_function(None, (_p, _p, _p, _i))


@intrinsic
def _call_mul_t(typingctx, address, res, mat, vec, nr, nc):
    """mju_mulMatTVec(res, mat, vec, nr, nc) at ``address``."""
    return _c_function(None, (_p, _p, _p, _i, _i))


@_jit
def _dot7(a, i, x):
    """Row i of a (3, 7) by x (7,): OpenBLAS ``dgemv_t`` (a 4-row block, a 3-row tail)."""
    r = (a[i, 0] * x[0] + a[i, 2] * x[2]) + (a[i, 1] * x[1] + a[i, 3] * x[3])
    return r + _fma(a[i, 6], x[6], _fma(a[i, 4], x[4], a[i, 5] * x[5]))


@_jit
def _dot9(a, i, x):
    """Row i of a (3, 9) by x (9,): OpenBLAS ``dgemv_t`` (rows 0-1 by its 2-column kernel,
    row 2 by its 1-column kernel, then a 1-row tail)."""
    p = np.empty(8)
    for k in range(8):
        p[k] = a[i, k] * x[k]
    if i < 2:
        r = (((p[0] + p[2]) + p[4]) + p[6]) + (((p[1] + p[3]) + p[5]) + p[7])
    else:
        r = ((p[0] + p[4]) + (p[2] + p[6])) + ((p[1] + p[5]) + (p[3] + p[7]))
    return _fma(a[i, 8], x[8], r)


@_jit
def _jjt(jp, i, k):
    """Entry (i, k) of J Jᵀ: OpenBLAS's one fused multiply-add per joint, in order."""
    acc = 0.0
    for j in range(N_ARM):
        acc = _fma(jp[i, j], jp[k, j], acc)
    return acc


@_jit
def _probe(jp, jf, s, orient, xmat, out):
    """The products as ``_solve`` computes them, for ``_agrees`` to compare with numpy's."""
    for i in range(3):
        for k in range(3):
            out[i, k] = _jjt(jp, i, k)
            out[i, 3 + k] = _jjt(jf, i, k)
        out[i, 6] = _dot7(jp, i, s)
        out[i, 7] = _dot7(jf, i, s)
        out[i, 8] = _dot9(orient, i, xmat)


@_jit
def _update(fp, jp, jt, out, nt, q, s, e, damp2, lo, hi, a, y, r, q_new, q_clip):
    """``PandaIK._update``: q_new and q_clip; whether a joint was clipped."""
    for i in range(3):
        for k in range(3):
            a[i, k] = _jjt(jp, i, k) + (damp2 if i == k else 0.0)
    _call_chol(fp[CHOL], a.ctypes.data, np.int32(3), 0.0)
    for i in range(3):
        r[i] = e[i] - _dot7(jp, i, s)
    _call_solve(fp[SOLVE], y.ctypes.data, a.ctypes.data, r.ctypes.data, np.int32(3))
    _call_mul_t(
        fp[MUL_T], out.ctypes.data, jt.ctypes.data, y.ctypes.data, np.int32(3), np.int32(nt)
    )
    clipped = False
    for j in range(N_ARM):
        qn = q[j] + (s[j] + out[j])
        q_new[j] = qn
        c = hi[j] if qn > hi[j] else (lo[j] if qn < lo[j] else qn)
        clipped = clipped or c != qn
        q_clip[j] = c
    return clipped


@_jit
def _solve(
    fp,
    m,
    d,
    site,
    xpos,
    xmat,
    q,
    jp_full,
    jr_full,
    w9,
    orient,
    target,
    iters,
    tol,
    ref,
    has_ref,
    orient_gain,
    posture,
    damp2,
    lo,
    hi,
):
    """``PandaIK._solve``: ``iters`` iterations towards ``target`` (world frame); the error."""
    tx, ty, tz = target[0], target[1], target[2]
    tol2 = tol * tol
    a, y, r = np.empty((3, 3)), np.empty(3), np.empty(3)
    s, ox, e = np.empty(N_ARM), np.empty(3), np.empty(3)
    q_new, q_clip = np.empty(N_ARM), np.empty(N_ARM)
    jp = np.empty((3, N_ARM))
    jf = np.empty((3, N_ARM))
    nv = jp_full.shape[1]
    site32 = np.int32(site)
    for _ in range(iters):
        e[0], e[1], e[2] = tx - xpos[0], ty - xpos[1], tz - xpos[2]
        if e[0] * e[0] + e[1] * e[1] + e[2] * e[2] < tol2:
            break
        _call_md(fp[COM], m, d)
        _call_jac(fp[JAC], m, d, jp_full.ctypes.data, jr_full.ctypes.data, site32)
        for i in range(3):
            ox[i] = _dot9(orient, i, xmat)
        _call_mul_t(
            fp[MUL_T],
            w9.ctypes.data,
            jr_full.ctypes.data,
            ox.ctypes.data,
            np.int32(3),
            np.int32(nv),
        )
        for j in range(N_ARM):
            s[j] = orient_gain * w9[j]
            if has_ref:
                s[j] = s[j] + posture * (ref[j] - q[j])
            for i in range(3):
                jp[i, j] = jp_full[i, j]
        if _update(fp, jp, jp_full, w9, nv, q, s, e, damp2, lo, hi, a, y, r, q_new, q_clip):
            # Joints at a limit drop out (their columns of J and entries of s times 0).
            for j in range(N_ARM):
                free = 1.0 if lo[j] <= q_new[j] <= hi[j] else 0.0
                s[j] = s[j] * free
                for i in range(3):
                    jf[i, j] = jp[i, j] * free
            _update(fp, jf, jf, w9, N_ARM, q, s, e, damp2, lo, hi, a, y, r, q_new, q_clip)
        for j in range(N_ARM):
            q[j] = q_clip[j]
        _call_md(fp[KIN], m, d)
    e0, e1, e2 = tx - xpos[0], ty - xpos[1], tz - xpos[2]
    return np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


@_jit
def _cell(v, low, step, top):
    """The seed table's index along one axis nearest ``v`` (round(): half to even), clipped."""
    return min(max(int(np.rint((v - low) / step)), 0), top)


@_jit
def reference(target, seeds, seed_low, seed_step, seed_top, no_ref):
    """``PandaIK.reference``: (the seed table's posture nearest the task-frame ``target``,
    whether there is one); ``no_ref`` where the table is empty or holds none there."""
    if seeds.shape[0] == 0:
        return no_ref, False
    ref = seeds[
        _cell(target[0], seed_low[0], seed_step[0], seed_top[0]),
        _cell(target[1], seed_low[1], seed_step[1], seed_top[1]),
        _cell(target[2], seed_low[2], seed_step[2], seed_top[2]),
    ]
    if np.isnan(ref[0]):
        return no_ref, False
    return ref, True


@_jit
def _solve_recover(
    fp, ptr, xpos, xmat, q, jp_full, jr_full, w9, orient, target, iters, tol, consts, seeds,
    seed_grid, seed_top, limits, no_ref,
):  # fmt: skip
    """``PandaIK.solve`` in one call: the task-frame ``target`` to the world's, the seed
    table's posture nearest it (``PandaIK.reference``; an empty table: none), ``_solve``, and
    the restart from that posture when the error stays above IK_RECOVER x ``tol``. Few
    arguments (numba's dispatch costs per argument): ``ptr`` = (model, data, site),
    ``consts`` = (lift x3, gains, λ², IK_RECOVER), ``seed_grid`` = (low; step), ``limits`` =
    (lo; hi)."""
    m, d, site = ptr[0], ptr[1], ptr[2]
    lift, seed_low, seed_step, lo, hi = consts[:3], seed_grid[0], seed_grid[1], limits[0], limits[1]
    orient_gain, posture, damp2, recover = consts[3], consts[4], consts[5], consts[6]
    world = np.empty(3)
    for i in range(3):
        world[i] = target[i] + lift[i]
    ref, has_ref = reference(target, seeds, seed_low, seed_step, seed_top, no_ref)
    args = (orient_gain, posture, damp2, lo, hi)
    err = _solve(
        fp, m, d, site, xpos, xmat, q, jp_full, jr_full, w9, orient, world, iters, tol, ref,
        has_ref, *args,
    )  # fmt: skip
    if err > recover * tol and has_ref:
        q_prev = q.copy()
        q[:] = ref
        _call_md(fp[KIN], m, d)
        err_ref = _solve(
            fp, m, d, site, xpos, xmat, q, jp_full, jr_full, w9, orient, world, 8 * iters, tol,
            ref, has_ref, *args,
        )  # fmt: skip
        if err_ref < err:
            err = err_ref
        else:
            q[:] = q_prev
            _call_md(fp[KIN], m, d)
    return err


@_jit
def _moved_recover(
    fp, ptr, xpos, xmat, q, jp_full, jr_full, w9, orient, moves, iters, tol, consts, seeds,
    seed_grid, seed_top, limits, no_ref, ctrl, out,
):  # fmt: skip
    """A clipped move and its solve in one call: the target (``out[0]``) is the state plus the
    two displacements, clipped to the box, as ``RobotTask.dynamics`` computes it:
    min(max((x + u_R) + u_H, low), high), ``moves`` = (x; u_H; u_R; low; high); then
    ``_solve_recover`` towards it, the actuators' ``ctrl`` set to the joints reached and the
    end effector in the task frame into ``out[1]``. Returns the remaining error."""
    for i in range(3):
        v = moves[0, i] + moves[2, i] + moves[1, i]
        v = moves[3, i] if v < moves[3, i] else v
        out[0, i] = moves[4, i] if v > moves[4, i] else v
    err = _solve_recover(
        fp, ptr, xpos, xmat, q, jp_full, jr_full, w9, orient, out[0], iters, tol, consts, seeds,
        seed_grid, seed_top, limits, no_ref,
    )  # fmt: skip
    for j in range(N_ARM):
        ctrl[j] = q[j]
    for i in range(3):
        out[1, i] = xpos[i] - consts[i]
    return err


def _addresses(symbols: tuple[str, ...] = _SYMBOLS) -> np.ndarray | None:
    """The C functions' addresses in MuJoCo's shared library (the one the binding loaded), in
    ``symbols``' order; None where there is no such library or a symbol is missing."""
    here = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        for path in sorted(glob.glob(os.path.join(here, pattern))):
            try:
                lib = ctypes.CDLL(path)
            except OSError:
                continue
            if all(hasattr(lib, s) for s in symbols):
                addr = [ctypes.cast(getattr(lib, s), ctypes.c_void_p).value for s in symbols]
                return np.array(addr, dtype=np.intp)
    return None


def _agrees(cases: int = 200) -> bool:
    """Whether the kernel's products equal numpy's (this process's BLAS) bit for bit on random
    Jacobians, in the layouts ``PandaIK`` uses: a (3, 7) view of MuJoCo's (3, 9) Jacobian, a
    (3, 7) copy (the limit step), and the (3, 9) gripper-down term. Another BLAS kernel
    (``OPENBLAS_CORETYPE``, another library) sums in another order: then the plain path runs."""
    rng = np.random.default_rng(0)
    out = np.empty((3, 9))
    for _ in range(cases):
        full, orient = rng.standard_normal((2, 3, 9))
        jp, jf = full[:, :N_ARM], np.ascontiguousarray(full[:, :N_ARM] * 0.5)
        s, xmat = rng.standard_normal(N_ARM), rng.standard_normal(9)
        _probe(jp, jf, s, orient, xmat, out)
        want = np.hstack([jp @ jp.T, jf @ jf.T, (jp @ s)[:, None], (jf @ s)[:, None]])
        want = np.hstack([want, (orient @ xmat)[:, None]])
        if want.tobytes() != out.tobytes():
            return False
    return True


@functools.cache
def solver() -> Callable[..., float] | None:
    """``_solve`` with MuJoCo's function addresses bound, or None: no binding addresses
    (``MjModel._address``), no library or symbols, or a BLAS that sums otherwise."""
    if not hasattr(mujoco.MjModel, "_address"):
        return None
    global _FP
    fp = _addresses()
    if fp is None or not _agrees():
        return None
    _FP = fp
    return functools.partial(_solve, fp)


def solve_arm(ik: Any, target: Any, iters: int, tol: float) -> float:
    """``PandaIK.solve`` (``ik``) by ``_solve_recover``; only where ``solver()`` is not None."""
    arm, (consts, table, grid, top), (limits, no_ref) = _arm_args(ik)
    target = np.asarray(target, dtype=np.float64)
    return _solve_recover(_FP, *arm, target, iters, tol, consts, table, grid, top, limits, no_ref)


def move_arm(
    ik: Any, moves: np.ndarray, iters: int, tol: float, ctrl: np.ndarray, out: np.ndarray
) -> float:
    """``_moved_recover`` on ``ik`` (a ``PandaIK``); only where ``solver()`` is not None."""
    arm, (consts, table, grid, top), (limits, no_ref) = _arm_args(ik)
    return _moved_recover(
        _FP, *arm, moves, iters, tol, consts, table, grid, top, limits, no_ref, ctrl, out
    )


def _arm_args(ik: Any) -> tuple:
    """The arm's views of its MuJoCo data and its constants, as the kernels read them (packed
    once per arm: numba's dispatch costs per argument)."""
    args = ik.__dict__.get("_kernel_args")
    if args is None:  # once per arm: views of its MuJoCo data and its constants
        d, site = ik.data, ik.site
        ptr = np.array([ik.model._address, d._address, site], dtype=np.intp)
        table, low, step, top = ik.seed_args
        args = ik._kernel_args = (
            (ptr, d.site_xpos[site], d.site_xmat[site], ik.q, ik._jp, ik._jr, ik._w9, ik._orient),
            (np.array([*ik.lift, *ik.kernel_gains]), table, np.vstack([low, step]), top),
            (np.vstack([ik.lo, ik.hi]), ik._no_ref),
        )
    return args


# ---------------------------------------------------------------------------- N arms
# ``BatchedPandaIK``'s one-arm step ``dls_step`` (and its ``dls_solve``) compiled from the very
# source CPython runs, for the restarts below and the lanes of ``ik_lanes``.

# dls_step's call of it compiles too; IEEE division (no zero check) lets the lanes vectorise
register_jitable(error_model="numpy")(dls_solve)
_dls = _jit(dls_step)


@_jit
def _one(p0, p1, p2):
    """A sum of 3 products as numpy's einsum adds them for a batch of one (its contiguous inner
    loop): (p0 + p2) + p1."""
    return (0.0 + p0 + p2) + p1


@_jit
def restart(
    fp, m, d, site, xpos, xmat, q, jp_full, jr_full, orient6, target, iters, tol, ref, og, pg,
    damp2, lo, hi,
):  # fmt: skip
    """``BatchedPandaIK._restart``: one arm on the single IK's model (MuJoCo's kinematics and
    Jacobian) with the batched IK's step; the remaining error."""
    tx, ty, tz = target[0], target[1], target[2]
    tol2 = tol * tol
    s, ql, q_new = np.empty(N_ARM), np.empty(N_ARM), np.empty(N_ARM)
    free = np.empty(N_ARM, dtype=np.bool_)
    site32 = np.int32(site)
    for j in range(N_ARM):
        ql[j] = q[j]
    for _ in range(iters):
        e0, e1, e2 = tx - xpos[0], ty - xpos[1], tz - xpos[2]
        if e0 * e0 + e1 * e1 + e2 * e2 < tol2:
            break
        _call_md(fp[COM], m, d)
        _call_jac(fp[JAC], m, d, jp_full.ctypes.data, jr_full.ctypes.data, site32)
        v = np.empty(3)
        for i in range(3):
            o = orient6[i]
            v[i] = (
                o[0] * xmat[0] + o[1] * xmat[2] + o[2] * xmat[3] + o[3] * xmat[5]
                + o[4] * xmat[6] + o[5] * xmat[8]
            )  # fmt: skip
        for j in range(N_ARM):
            a, b, c = jr_full[0, j], jr_full[1, j], jr_full[2, j]
            s[j] = og * (a * v[0] + b * v[1] + c * v[2]) + pg * (ref[j] - ql[j])
            free[j] = True
        _dls(ql, jp_full[0], jp_full[1], jp_full[2], s, e0, e1, e2, damp2, free, q_new)
        hit = False
        for j in range(N_ARM):
            free[j] = lo[j] <= q_new[j] <= hi[j]
            hit = hit or not free[j]
        if hit:
            _dls(ql, jp_full[0], jp_full[1], jp_full[2], s, e0, e1, e2, damp2, free, q_new)
        for j in range(N_ARM):
            qn = q_new[j]
            ql[j] = hi[j] if qn > hi[j] else (lo[j] if qn < lo[j] else qn)
            q[j] = ql[j]
        _call_md(fp[KIN], m, d)
    e0, e1, e2 = tx - xpos[0], ty - xpos[1], tz - xpos[2]
    return np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


@functools.cache
def addresses() -> np.ndarray | None:
    """MuJoCo's function addresses for ``restart`` (None: as ``solver``'s, no kernel)."""
    if not hasattr(mujoco.MjModel, "_address") or solver() is None:
        return None
    return _addresses()
