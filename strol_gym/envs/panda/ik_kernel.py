"""``PandaIK._solve`` as one compiled loop (numba) that calls MuJoCo's C functions itself.

The C-calling kernel: ``mj_kinematics``, ``mj_comPos``, ``mj_jacSite`` and MuJoCo's Cholesky and
Jᵀ products are the very calls of the plain path, reached through ``libmujoco``'s exported
symbols and the private ``MjModel._address`` / ``MjData._address`` of the Python binding. The
3x7 algebra that the plain path leaves to numpy's BLAS (OpenBLAS) is written out in the order
and with the fused multiply-adds that OpenBLAS's kernels use on this machine (J Jᵀ: one fused
multiply-add per joint, in order; J s and the gripper-down term: ``dgemv_t``'s pairwise sums
and its fused tail), so every iteration reaches the same bits (tests/test_kernels.py compares
both paths on fixed seeds; a BLAS that sums differently shows there first).

Not cached on disk: the C functions' addresses are compiled in and change per process, so the
kernel compiles on first use (about a second, ``benchmarks/speed/chains.py`` prints it).
Without the binding's addresses or the symbols (another MuJoCo build), ``solver()`` is None and
the plain path runs.
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

from strol_gym.compiled import _numba, use_fast
from strol_gym.envs.panda.model import N_ARM

_SYMBOLS = (
    "mj_kinematics",
    "mj_comPos",
    "mj_jacSite",
    "mju_cholFactor",
    "mju_cholSolve",
    "mju_mulMatTVec",
)


def _library() -> ctypes.CDLL | None:
    """MuJoCo's shared library as the Python binding loaded it, with the symbols used here."""
    here = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        for path in sorted(glob.glob(os.path.join(here, pattern))):
            try:
                lib = ctypes.CDLL(path)
            except OSError:
                continue
            if all(hasattr(lib, s) for s in _SYMBOLS):
                return lib
    return None


@functools.cache
def _compiled() -> Callable[..., Any] | None:
    numba = _numba()
    lib = _library()
    if numba is None or lib is None:
        return None
    ptr, dbl, i32 = ctypes.c_size_t, ctypes.c_double, ctypes.c_int
    sigs = {
        "mj_kinematics": (None, [ptr, ptr]),
        "mj_comPos": (None, [ptr, ptr]),
        "mj_jacSite": (None, [ptr, ptr, ptr, ptr, i32]),
        "mju_cholFactor": (i32, [ptr, i32, dbl]),
        "mju_cholSolve": (None, [ptr, ptr, ptr, i32]),
        "mju_mulMatTVec": (None, [ptr, ptr, ptr, i32, i32]),
    }
    fns = {}
    for name, (res, args) in sigs.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
        fns[name] = fn
    kinematics, com_pos, jac_site = fns["mj_kinematics"], fns["mj_comPos"], fns["mj_jacSite"]
    chol_factor, chol_solve, mul_t = (
        fns["mju_cholFactor"],
        fns["mju_cholSolve"],
        fns["mju_mulMatTVec"],
    )
    fma = _fma(numba)
    jit = numba.njit(cache=False, nogil=True)

    @jit
    def dot7(a: Any, i: int, x: Any) -> float:
        """Row i of a (3, 7) by x (7,): OpenBLAS ``dgemv_t`` (a 4-row block, a 3-row tail)."""
        r = (a[i, 0] * x[0] + a[i, 2] * x[2]) + (a[i, 1] * x[1] + a[i, 3] * x[3])
        return r + fma(a[i, 6], x[6], fma(a[i, 4], x[4], a[i, 5] * x[5]))

    @jit
    def dot9(a: Any, i: int, x: Any) -> float:
        """Row i of a (3, 9) by x (9,): OpenBLAS ``dgemv_t`` (rows 0-1 by its 2-column kernel,
        row 2 by its 1-column kernel, then a 1-row tail)."""
        p = np.empty(8)
        for k in range(8):
            p[k] = a[i, k] * x[k]
        if i < 2:
            r = (((p[0] + p[2]) + p[4]) + p[6]) + (((p[1] + p[3]) + p[5]) + p[7])
        else:
            r = ((p[0] + p[4]) + (p[2] + p[6])) + ((p[1] + p[5]) + (p[3] + p[7]))
        return fma(a[i, 8], x[8], r)

    @jit
    def jjt(jp: Any, i: int, k: int) -> float:
        """Entry (i, k) of J Jᵀ: OpenBLAS's one fused multiply-add per joint, in order."""
        acc = 0.0
        for j in range(N_ARM):
            acc = fma(jp[i, j], jp[k, j], acc)
        return acc

    @jit
    def probe(jp, jf, s, orient, xmat, out):
        """The products as ``solve`` computes them, for ``_agrees`` to compare with numpy's."""
        for i in range(3):
            for k in range(3):
                out[i, k] = jjt(jp, i, k)
                out[i, 3 + k] = jjt(jf, i, k)
            out[i, 6] = dot7(jp, i, s)
            out[i, 7] = dot7(jf, i, s)
            out[i, 8] = dot9(orient, i, xmat)

    if not _agrees(probe):
        return None

    @jit
    def update(jp, jt, out, nt, q, s, e, damp2, lo, hi, a, y, r, q_new, q_clip) -> bool:
        """``PandaIK._update``: q_new and q_clip; whether a joint was clipped."""
        for i in range(3):
            for k in range(3):
                a[i, k] = jjt(jp, i, k) + (damp2 if i == k else 0.0)
        chol_factor(a.ctypes.data, 3, 0.0)
        for i in range(3):
            r[i] = e[i] - dot7(jp, i, s)
        chol_solve(y.ctypes.data, a.ctypes.data, r.ctypes.data, 3)
        mul_t(out.ctypes.data, jt.ctypes.data, y.ctypes.data, 3, nt)
        clipped = False
        for j in range(N_ARM):
            qn = q[j] + (s[j] + out[j])
            q_new[j] = qn
            c = hi[j] if qn > hi[j] else (lo[j] if qn < lo[j] else qn)
            clipped = clipped or c != qn
            q_clip[j] = c
        return clipped

    @jit
    def solve(
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
    ) -> float:
        tx, ty, tz = target[0], target[1], target[2]
        tol2 = tol * tol
        a, y, r = np.empty((3, 3)), np.empty(3), np.empty(3)
        s, ox = np.empty(N_ARM), np.empty(3)
        q_new, q_clip = np.empty(N_ARM), np.empty(N_ARM)
        jp = jp_full[:, :N_ARM]
        jf = np.empty((3, N_ARM))
        nv = jp_full.shape[1]
        e = np.empty(3)
        for _ in range(iters):
            e[0], e[1], e[2] = tx - xpos[0], ty - xpos[1], tz - xpos[2]
            if e[0] * e[0] + e[1] * e[1] + e[2] * e[2] < tol2:
                break
            com_pos(m, d)
            jac_site(m, d, jp_full.ctypes.data, jr_full.ctypes.data, site)
            for i in range(3):
                ox[i] = dot9(orient, i, xmat)
            mul_t(w9.ctypes.data, jr_full.ctypes.data, ox.ctypes.data, 3, nv)
            for j in range(N_ARM):
                s[j] = orient_gain * w9[j]
                if has_ref:
                    s[j] = s[j] + posture * (ref[j] - q[j])
            jpc = np.ascontiguousarray(jp)
            if update(jpc, jp_full, w9, nv, q, s, e, damp2, lo, hi, a, y, r, q_new, q_clip):
                for j in range(N_ARM):
                    free = 1.0 if lo[j] <= q_new[j] <= hi[j] else 0.0
                    s[j] = s[j] * free
                    for i in range(3):
                        jf[i, j] = jp[i, j] * free
                update(jf, jf, w9, N_ARM, q, s, e, damp2, lo, hi, a, y, r, q_new, q_clip)
            for j in range(N_ARM):
                q[j] = q_clip[j]
            kinematics(m, d)
        e0, e1, e2 = tx - xpos[0], ty - xpos[1], tz - xpos[2]
        return np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)

    return solve


def _agrees(probe: Callable[..., None], cases: int = 200) -> bool:
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
        probe(jp, jf, s, orient, xmat, out)
        want = np.hstack([jp @ jp.T, jf @ jf.T, (jp @ s)[:, None], (jf @ s)[:, None]])
        want = np.hstack([want, (orient @ xmat)[:, None]])
        if want.tobytes() != out.tobytes():
            return False
    return True


def _fma(numba: Any) -> Callable[[float, float, float], float]:
    """A fused multiply-add a·b + c (LLVM's ``llvm.fma.f64``) usable in numba code."""
    from llvmlite import ir
    from numba.core import cgutils, types
    from numba.extending import intrinsic

    @intrinsic
    def fma(typingctx, a, b, c):
        sig = types.float64(types.float64, types.float64, types.float64)

        def codegen(context, builder, signature, args):
            d = ir.DoubleType()
            fnty = ir.FunctionType(d, [d, d, d])
            fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.fma.f64")
            return builder.call(fn, args)

        return sig, codegen

    return fma


def solver() -> Callable[..., Any] | None:
    """The compiled ``PandaIK._solve`` when fast kernels are on and MuJoCo's symbols and the
    binding's addresses are there; None otherwise (the plain path runs)."""
    if not use_fast() or not hasattr(mujoco.MjModel, "_address"):
        return None
    return _compiled()
