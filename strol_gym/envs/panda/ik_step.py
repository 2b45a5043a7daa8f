"""The batched IK's update for one arm (``dls_step``), in plain floats: one source that CPython
runs (``BatchedPandaIK._restart``, on lists) and numba compiles (``ik_kernel``, on arrays), so
that the batched IK's algebra is written twice only, here and in ``BatchedPandaIK._step``."""

from __future__ import annotations

import math
from typing import Any

from strol_gym.envs.panda.model import N_ARM


def dls_step(
    q: Any,
    j0: Any,
    j1: Any,
    j2: Any,
    s: Any,
    e0: float,
    e1: float,
    e2: float,
    damp: float,
    free: Any,
    out: Any,
    alone: bool = False,
) -> None:
    """q + s + Jᵀ (J Jᵀ + λ²I)⁻¹ (e − J s) for one arm into ``out``, J by rows ``j0``-``j2``:
    the operations of ``ik_batched.BatchedPandaIK._step``, summed in the same order, on one
    arm's numbers.
    Joints whose ``free`` is false drop out: their columns of J and entries of s are left out of
    the sums (the batched step's products by 0, which add nothing) and they stay where they are.

    ``alone``: Jᵀ y sums as numpy's einsum does for a batch of one arm, (term 0 + term 2) +
    term 1 (its contiguous inner loop), instead of in order.

    One source for two readers: CPython runs it on lists (``_restart``, where numpy's per-call
    cost on 3 and 7 numbers dominates) and ``ik_kernel`` compiles it for arrays, so the batched
    IK's algebra is written here and in ``_step`` only."""
    a00 = a11 = a22 = a10 = a20 = a21 = v0 = v1 = v2 = 0.0
    for j in range(N_ARM):
        if free[j]:
            a, b, c, sj = j0[j], j1[j], j2[j], s[j]
            a00 += a * a
            a11 += b * b
            a22 += c * c
            a10 += b * a
            a20 += c * a
            a21 += c * b
            v0 += a * sj
            v1 += b * sj
            v2 += c * sj
    y0, y1, y2 = dls_solve(a00, a11, a22, a10, a20, a21, e0 - v0, e1 - v1, e2 - v2, damp)
    for j in range(N_ARM):
        if not free[j]:
            out[j] = q[j]
        elif alone:
            out[j] = q[j] + (s[j] + ((0.0 + j0[j] * y0 + j2[j] * y2) + j1[j] * y1))
        else:
            out[j] = q[j] + (s[j] + (0.0 + j0[j] * y0 + j1[j] * y1 + j2[j] * y2))


def dls_solve(
    a00: float,
    a11: float,
    a22: float,
    a10: float,
    a20: float,
    a21: float,
    r0: float,
    r1: float,
    r2: float,
    damp: float,
) -> tuple[float, float, float]:
    """y = (A + λ²I)⁻¹ r for the symmetric 3x3 A = J Jᵀ (its lower triangle) and λ² = ``damp``,
    by Cholesky: the operations of ``BatchedPandaIK._step``, in its order (``dls_step`` and the
    compiled batched IK's lanes call it with r = e − J s)."""
    l00 = math.sqrt(a00 + damp)
    l10, l20 = a10 / l00, a20 / l00
    l11 = math.sqrt(a11 + damp - l10 * l10)
    l21 = (a21 - l20 * l10) / l11
    l22 = math.sqrt(a22 + damp - l20 * l20 - l21 * l21)
    z0 = r0 / l00
    z1 = (r1 - l10 * z0) / l11
    y2 = (r2 - l20 * z0 - l21 * z1) / l22 / l22
    y1 = (z1 - l21 * y2) / l11
    y0 = (z0 - l10 * y1 - l20 * y2) / l00
    return y0, y1, y2


ALL_FREE = [True] * N_ARM
