"""``BatchedPandaIK``'s compiled kernels, over lanes of arms (numba).

The arms that still iterate are copied into *lanes*: working arrays with the arms along their
last, contiguous axis, packed (an arm that converges leaves its lane and is written back). Each
step of an iteration is a loop over the lanes with the same operations on every lane, which the
compiler runs several arms at a time (SIMD) on contiguous numbers; only the sines and cosines
(the C library's, one call each) go one arm at a time. The arms that hit a joint limit redo
their step in lanes of their own. Each arm's
operations are those of the plain path, in its order (the link products as OpenBLAS's
``dgemm``: one fused multiply-add per term, in order, from 0; ``einsum``'s sums in order, from
0), so the bits are its bits: ``ik_batched.compiled_kernels`` checks that once per process.

The arms keep numpy's *lockstep* (``ik_batched.BatchedPandaIK._solve``): the set that iterates,
its compaction below ``compact``, and the arms that hit a joint limit together, because numpy
sums some products in another order for a batch of one arm (``ik_kernel._one``). Only the set's
size enters the numbers, so the lanes hold just the arms that move.

This module imports numba: import it only when ``strol_gym.compiled.use_fast()``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from strol_gym.envs.panda.ik_kernel import (
    _cell,
    _dls,
    _dot9,
    _fma,
    _one,
    addresses,
    restart,
)
from strol_gym.envs.panda.ik_step import dls_solve
from strol_gym.envs.panda.model import N_ARM

__all__ = ["addresses", "batched_forward", "batched_solve", "references", "restart"]

_jit: Any = njit(cache=True, nogil=True, error_model="numpy")
"""IEEE division (inf or NaN, no ZeroDivisionError branch), so that the lanes' loops vectorise;
the divisors here are square roots of damped sums, never 0."""


@_jit
def _lanes_fk(q, site, cols, axes, anchors, n, base_cols, base_pos, links, site_link, trig, f, rot):
    """``BatchedPandaIK._fk`` of lanes 0..n-1: kinematics from the joint angles ``q`` (7, L),
    in place (``site`` (3, L), ``cols`` (3, 3, L), ``axes`` and ``anchors`` (7, 3, L));
    ``trig`` (2, 7, L), ``f`` (4, 3, L) and ``rot`` (3, 3, L) are scratch."""
    c, sn = trig[0], trig[1]
    for j in range(N_ARM):  # the C library's cosine and sine, one arm at a time
        for lane in range(n):
            c[j, lane] = np.cos(q[j, lane])
            sn[j, lane] = np.sin(q[j, lane])
    for k in range(3):
        x0, y0, z0, p = base_cols[0, k], base_cols[1, k], base_cols[2, k], base_pos[k]
        for lane in range(n):
            axes[0, k, lane] = z0
            anchors[0, k, lane] = p
            f[0, k, lane] = x0
            f[1, k, lane] = y0
    for j in range(N_ARM):
        if j:  # the next body's frame (rows 0-2) and its offset (row 3): links[j] @ rot
            for k in range(3):
                for i in range(4):
                    l0, l1, l2 = links[j, i, 0], links[j, i, 1], links[j, i, 2]
                    for lane in range(n):
                        f[i, k, lane] = _fma(
                            l2,
                            rot[2, k, lane],
                            _fma(l1, rot[1, k, lane], _fma(l0, rot[0, k, lane], 0.0)),
                        )
                for lane in range(n):
                    anchors[j, k, lane] = anchors[j - 1, k, lane] + f[3, k, lane]
                    axes[j, k, lane] = f[2, k, lane]
        for k in range(3):
            # x' = c x + s y, y' = c y − s x, z' = z (the hinge about the body's z axis)
            for lane in range(n):
                cj, sj = c[j, lane], sn[j, lane]
                x, y = f[0, k, lane], f[1, k, lane]
                rot[0, k, lane] = x * cj + y * sj
                rot[1, k, lane] = y * cj + x * -sj
                rot[2, k, lane] = axes[j, k, lane]
    for k in range(3):
        for i in range(4):
            l0, l1, l2 = site_link[i, 0], site_link[i, 1], site_link[i, 2]
            for lane in range(n):
                x = _fma(
                    l2, rot[2, k, lane], _fma(l1, rot[1, k, lane], _fma(l0, rot[0, k, lane], 0.0))
                )
                if i < 3:
                    cols[i, k, lane] = x
                else:
                    site[k, lane] = anchors[N_ARM - 1, k, lane] + x


@_jit
def _dls_lanes(q, jt, s, e, damp, out, n, sums):
    """``ik_step.dls_step`` for lanes 0..n-1, every joint free, summed in its order (its sums and
    its last line over lanes; ``dls_solve`` itself): q (7, L), J by rows ``jt`` (3, 7, L),
    s (7, L), e (3, L) into ``out`` (7, L); ``sums`` (9, L) is scratch."""
    for c in range(9):
        for lane in range(n):
            sums[c, lane] = 0.0
    for j in range(N_ARM):
        for lane in range(n):
            a, b, c, sj = jt[0, j, lane], jt[1, j, lane], jt[2, j, lane], s[j, lane]
            sums[0, lane] += a * a
            sums[1, lane] += b * b
            sums[2, lane] += c * c
            sums[3, lane] += b * a
            sums[4, lane] += c * a
            sums[5, lane] += c * b
            sums[6, lane] += a * sj
            sums[7, lane] += b * sj
            sums[8, lane] += c * sj
    for lane in range(n):  # y into the first three sums
        sums[0, lane], sums[1, lane], sums[2, lane] = dls_solve(
            sums[0, lane], sums[1, lane], sums[2, lane], sums[3, lane], sums[4, lane],
            sums[5, lane], e[0, lane] - sums[6, lane], e[1, lane] - sums[7, lane],
            e[2, lane] - sums[8, lane], damp,
        )  # fmt: skip
    for j in range(N_ARM):
        for lane in range(n):
            y0, y1, y2 = sums[0, lane], sums[1, lane], sums[2, lane]
            t = 0.0 + jt[0, j, lane] * y0 + jt[1, j, lane] * y1 + jt[2, j, lane] * y2
            out[j, lane] = q[j, lane] + (s[j, lane] + t)


@_jit
def _dls_step(q, jt, s, e, damp, out, n, alone, sums, one):
    """``ik_step.dls_step`` (every joint free) for lanes 0..n-1: ``alone`` (a batch of one arm,
    n = 1) by ``dls_step`` itself, on ``one`` (6, 7) as scratch; else ``_dls_lanes``."""
    if not alone:
        _dls_lanes(q, jt, s, e, damp, out, n, sums)
        return
    ja, jb, jc, sa, qa, qo = one[0], one[1], one[2], one[3], one[4], one[5]
    for j in range(N_ARM):
        ja[j], jb[j], jc[j], sa[j], qa[j] = jt[0, j, 0], jt[1, j, 0], jt[2, j, 0], s[j, 0], q[j, 0]
    _dls(qa, ja, jb, jc, sa, e[0, 0], e[1, 0], e[2, 0], damp, ALL_FREE, qo, True)
    for j in range(N_ARM):
        out[j, 0] = qo[j]


ALL_FREE = np.ones(N_ARM, dtype=np.bool_)
PACK = 4
"""The lanes are packed when at least 1/PACK of them (or all but one) are within tolerance;
until then those are held still (packing every arm's numbers costs more than a few steps)."""


@_jit
def _gather(src, dst, rows, lane_of, n):
    """dst[..., l] = src[..., rows[lane_of[l]]] for the first n lanes (src, dst 2-d)."""
    for c in range(src.shape[0]):
        for lane in range(n):
            dst[c, lane] = src[c, rows[lane_of[lane]]]


@_jit
def _scatter(dst, src, rows, lane_of, lanes):
    """dst[..., rows[lane_of[l]]] = src[..., l] for the lanes ``lanes``."""
    for c in range(src.shape[0]):
        for lane in lanes:
            dst[c, rows[lane_of[lane]]] = src[c, lane]


@_jit
def _pack(a, keep, n):
    """Moves the kept lanes of ``a`` (2-d) to its front, in order."""
    for c in range(a.shape[0]):
        k = 0
        for lane in range(n):
            if keep[lane]:
                a[c, k] = a[c, lane]
                k += 1


@_jit
def references(target, seeds, seed_low, seed_step, seed_top, out):
    """``BatchedPandaIK.reference`` of task-frame targets (B, 3) into ``out`` (B, 7): the
    table's row at each target's cell (``ik_kernel._cell``: numpy's rounding and clip), NaN
    where it holds no posture, as the table's own rows."""
    for b in range(target.shape[0]):
        i = _cell(target[b, 0], seed_low[0], seed_step[0], seed_top[0])
        j = _cell(target[b, 1], seed_low[1], seed_step[1], seed_top[1])
        k = _cell(target[b, 2], seed_low[2], seed_step[2], seed_top[2])
        for m in range(N_ARM):
            out[b, m] = seeds[i, j, k, m]


@_jit
def batched_forward(q, site, cols, axes, anchors, rows, base_cols, base_pos, links, site_link):
    """``BatchedPandaIK._fk`` of arms ``rows``."""
    n = rows.shape[0]
    lane_of = np.arange(n)
    wq = np.empty((N_ARM, n))
    _gather(q, wq, rows, lane_of, n)
    w_site, w_cols = np.empty((3, n)), np.empty((3, 3, n))
    w_axes, w_anch = np.empty((N_ARM, 3, n)), np.empty((N_ARM, 3, n))
    trig, f, rot = np.empty((2, N_ARM, n)), np.empty((4, 3, n)), np.empty((3, 3, n))
    _lanes_fk(
        wq, w_site, w_cols, w_axes, w_anch, n, base_cols, base_pos, links, site_link, trig, f, rot
    )
    every = np.arange(n)
    _scatter(site, w_site, rows, lane_of, every)
    _scatter(cols.reshape(9, -1), w_cols.reshape(9, n), rows, lane_of, every)
    _scatter(axes.reshape(3 * N_ARM, -1), w_axes.reshape(3 * N_ARM, n), rows, lane_of, every)
    _scatter(anchors.reshape(3 * N_ARM, -1), w_anch.reshape(3 * N_ARM, n), rows, lane_of, every)


@_jit
def batched_solve(
    q, site, cols, axes, anchors, rows, target, iters, tol, ref, has_ref, moving, base_cols,
    base_pos, links, site_link, orient_cols, orient_gain, posture, damp2, lo, hi, compact,
):  # fmt: skip
    """``BatchedPandaIK._solve``: arms ``rows`` iterate towards world-frame ``target`` (3, B)
    until within ``tol`` or ``iters``; ``moving`` (B,): those not yet within it, updated."""
    nb = rows.shape[0]
    tol2 = tol * tol
    lane_of, every = np.empty(nb, dtype=np.intp), np.arange(nb)
    n = 0
    for b in range(nb):
        if moving[b]:
            lane_of[n] = b
            n += 1
    # The lanes: each arm's state, then its target, reference posture and whether it has one.
    wq, w_site, w_cols = np.empty((N_ARM, nb)), np.empty((3, nb)), np.empty((3, 3, nb))
    w_axes, w_anch = np.empty((N_ARM, 3, nb)), np.empty((N_ARM, 3, nb))
    w_tgt, w_ref, w_has = np.empty((3, nb)), np.empty((N_ARM, nb)), np.empty((1, nb))
    state = (wq, w_site, w_cols.reshape(9, nb), w_axes.reshape(21, nb), w_anch.reshape(21, nb))
    arms = (q, site, cols.reshape(9, -1), axes.reshape(21, -1), anchors.reshape(21, -1))
    for c in range(len(state)):
        _gather(arms[c], state[c], rows, lane_of, n)
    _gather(target, w_tgt, every, lane_of, n)
    _gather(ref, w_ref, every, lane_of, n)
    _gather(has_ref.reshape(1, nb).astype(np.float64), w_has, every, lane_of, n)
    e, keep, stepped = np.empty((3, nb)), np.empty(nb, dtype=np.bool_), np.empty((1, nb))
    jt, v = np.empty((3, N_ARM, nb)), np.empty((3, nb))
    s, q_new = np.empty((N_ARM, nb)), np.empty((N_ARM, nb))
    trig, f, rot = np.empty((2, N_ARM, nb)), np.empty((4, 3, nb)), np.empty((3, 3, nb))
    flat, one, sums = np.empty(9), np.empty((6, N_ARM)), np.empty((9, nb))
    hit, hit_of = np.empty(nb, dtype=np.bool_), np.empty(nb, dtype=np.intp)
    h_jt, h_s, h_q = np.empty((3, N_ARM, nb)), np.empty((N_ARM, nb)), np.empty((N_ARM, nb))
    h_e, h_out = np.empty((3, nb)), np.empty((N_ARM, nb))
    keep[:n] = True
    stepped[0, :n] = 0.0  # lanes whose numbers are this call's (written back), not the arms'
    size = nb  # the lockstep's set: the lanes and the arms it holds still
    for _ in range(iters):
        live = 0
        for lane in range(n):
            e0 = w_tgt[0, lane] - w_site[0, lane]
            e1 = w_tgt[1, lane] - w_site[1, lane]
            e2 = w_tgt[2, lane] - w_site[2, lane]
            e[0, lane], e[1, lane], e[2, lane] = e0, e1, e2
            p0, p1, p2 = e0 * e0, e1 * e1, e2 * e2
            n2 = _one(p0, p1, p2) if size == 1 else ((0.0 + p0) + p1) + p2
            keep[lane] = keep[lane] and n2 >= tol2
            live += keep[lane]
        if live < n and (live <= 1 or PACK * (n - live) >= n):
            # The arms within tolerance leave their lanes, written back. Fewer of them stay
            # (held still: their steps are computed and dropped, their kinematics redone; an arm
            # held before its first step keeps its own numbers, which may be MuJoCo's).
            gone = np.flatnonzero(~keep[:n])
            for c in range(len(state)):
                _scatter(arms[c], state[c], rows, lane_of, gone[stepped[0, gone] != 0.0])
            for g in gone:
                moving[lane_of[g]] = False
            for w in state:
                _pack(w, keep, n)
            for w in (w_tgt, w_ref, w_has, e):
                _pack(w, keep, n)
            _pack(lane_of.reshape(1, nb), keep, n)
            _pack(stepped, keep, n)
            keep[:live] = True
            n = live
        if not live:
            break
        if live < compact * size:
            size = live
        alone = size == 1
        for j in range(N_ARM):  # the position Jacobian's column j: axis_j × (site − anchor_j)
            for lane in range(n):
                d0 = w_site[0, lane] - w_anch[j, 0, lane]
                d1 = w_site[1, lane] - w_anch[j, 1, lane]
                d2 = w_site[2, lane] - w_anch[j, 2, lane]
                x, y, z = w_axes[j, 0, lane], w_axes[j, 1, lane], w_axes[j, 2, lane]
                jt[0, j, lane] = y * d2 - z * d1
                jt[1, j, lane] = z * d0 - x * d2
                jt[2, j, lane] = x * d1 - y * d0
        # The gripper-down term: a matrix product; for one arm, a matrix-vector product.
        for i in range(3):
            if alone:
                for m in range(9):
                    flat[m] = w_cols[m // 3, m % 3, 0]
                v[i, 0] = _dot9(orient_cols, i, flat)
                continue
            for lane in range(n):
                v[i, lane] = 0.0
            for m in range(9):
                o = orient_cols[i, m]
                for lane in range(n):
                    v[i, lane] = _fma(o, w_cols[m // 3, m % 3, lane], v[i, lane])
        for j in range(N_ARM):
            for lane in range(n):
                p0 = w_axes[j, 0, lane] * v[0, lane]
                p1 = w_axes[j, 1, lane] * v[1, lane]
                p2 = w_axes[j, 2, lane] * v[2, lane]
                sj = _one(p0, p1, p2) if alone else ((0.0 + p0) + p1) + p2
                sj = sj * orient_gain
                with_ref = sj + posture * (w_ref[j, lane] - wq[j, lane])
                s[j, lane] = with_ref if w_has[0, lane] else sj
        _dls_step(wq, jt, s, e, damp2, q_new, n, alone, sums, one)
        n_hit = 0
        for lane in range(n):
            h = False
            for j in range(N_ARM):
                h = h or q_new[j, lane] < lo[j] or q_new[j, lane] > hi[j]
            h = h and keep[lane]  # a held lane does not step
            hit[lane] = h
            n_hit += h
        if n_hit:  # the arms that hit a limit redo their step together, in lanes of their own
            k = 0
            for lane in range(n):
                if hit[lane]:
                    hit_of[k] = lane
                    k += 1
            # Joints at a limit drop out (their columns of J and entries of s times 0).
            for j in range(N_ARM):
                lj, hj = lo[j], hi[j]
                for t in range(k):
                    lane = hit_of[t]
                    fj = 0.0 if q_new[j, lane] < lj or q_new[j, lane] > hj else 1.0
                    h_jt[0, j, t] = jt[0, j, lane] * fj
                    h_jt[1, j, t] = jt[1, j, lane] * fj
                    h_jt[2, j, t] = jt[2, j, lane] * fj
                    h_s[j, t], h_q[j, t] = s[j, lane] * fj, wq[j, lane]
            for i in range(3):
                for t in range(k):
                    h_e[i, t] = e[i, hit_of[t]]
            _dls_step(h_q, h_jt, h_s, h_e, damp2, h_out, k, k == 1, sums, one)
            for j in range(N_ARM):
                for t in range(k):
                    q_new[j, hit_of[t]] = h_out[j, t]
        for j in range(N_ARM):
            lj, hj = lo[j], hi[j]
            for lane in range(n):
                qn = q_new[j, lane]
                qn = qn if qn != qn or qn >= lj else lj  # np.maximum: NaN stays
                qn = qn if qn != qn or qn <= hj else hj
                wq[j, lane] = qn if keep[lane] else wq[j, lane]
        for lane in range(n):
            stepped[0, lane] = 1.0 if keep[lane] else stepped[0, lane]
        _lanes_fk(
            wq, w_site, w_cols, w_axes, w_anch, n, base_cols, base_pos, links, site_link, trig, f,
            rot,
        )  # fmt: skip
    for c in range(len(state)):
        _scatter(arms[c], state[c], rows, lane_of, np.flatnonzero(stepped[0, :n] != 0.0))
    for lane in range(n):
        moving[lane_of[lane]] = keep[lane]
