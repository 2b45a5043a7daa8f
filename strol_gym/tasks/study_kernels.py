"""StROL-Study-v2's plan walk (``strol_gym.tasks.study._walk_out``) as a compiled loop (numba,
through ``strol_gym.compiled``): the planner calls it on every iterate, and the plain path's
~60 numpy calls per waypoint on arrays of a few dozen numbers cost more than the arithmetic.

The loop repeats, number for number, the IEEE operations of the plain path in the same order
and without fast-math (``hypot`` is the C library's in both), so it walks every plan to the bit
(tests/test_compiled.py). Two of the plain path's tests are over the whole batch, not per plan
(whether any step crosses a half-space, whether any step is cut): the loop keeps them so, the
waypoints over the batch at each step, so that a plan's bits are the same as the plain path's
in any batch.
"""

from __future__ import annotations

import math

import numpy as np

from strol_gym.compiled import compiled


@compiled
def _min(a: float, b: float) -> float:
    """numpy's ``minimum`` of two doubles: NaN propagates from either; of equal ones, ``b``."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a < b else b


@compiled
def _max(a: float, b: float) -> float:
    """numpy's ``maximum`` of two doubles: NaN propagates from either; of equal ones, ``b``."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a > b else b


@compiled
def walk_out(
    plans: np.ndarray,
    out: np.ndarray,
    hulls: np.ndarray,
    bound: float,
    low: np.ndarray,
    high: np.ndarray,
    rounds: int,
    group: int,
) -> None:
    """``_walk_out`` on plans (N, T+1, s) into ``out`` (a copy of them: only its positions
    are written); ``hulls`` (k, 4), ``low``/``high`` (3,), ``rounds`` = ``WALK_ROUNDS``; the
    plans walked together in consecutive groups of ``group`` (one θ's: its plans do not
    depend on the other groups)."""
    n_rows, n_t = plans.shape[0], plans.shape[1]
    k = hulls.shape[0]
    lo = np.empty((n_rows, 3))
    hi = np.empty((n_rows, 3))
    for r in range(n_rows):
        for c in range(3):
            lo[r, c] = _min(low[c], out[r, 0, c])
            hi[r, c] = _max(high[c], out[r, 0, c])
    nrm = np.empty((n_rows, k, 3))
    need = np.empty((n_rows, k))
    short = np.empty((n_rows, k))
    outside = np.empty((n_rows, k), dtype=np.bool_)
    q = np.empty((n_rows, 3))
    push = np.empty((k, 3))
    for first in range(0, n_rows, group):
        for t in range(1, n_t):
            any_short = False
            for r in range(first, first + group):
                p0, p1, p2 = out[r, t - 1, 0], out[r, t - 1, 1], out[r, t - 1, 2]
                for j in range(k):
                    a0, a1 = p0 - hulls[j, 0], p1 - hulls[j, 1]
                    rho = _max(math.hypot(a0, a1), 1e-12)
                    dr, dz = rho - hulls[j, 2], p2 - hulls[j, 3]
                    out_j = (dr > 0) or (dz > 0)
                    outside[r, j] = out_j
                    if out_j:
                        clear = math.hypot(_max(dr, 0.0), _max(dz, 0.0))
                    else:
                        clear = _max(dr, dz)
                    edge = (dr > 0) and (dz > 0)
                    if edge:
                        side, up = dr, dz
                    else:
                        side = 1.0 if dr > dz else 0.0
                        up = 1.0 if dr <= dz else 0.0
                    norm = math.hypot(side, up)
                    f = side / (rho * norm)
                    nrm[r, j, 0] = a0 * f
                    nrm[r, j, 1] = a1 * f
                    nrm[r, j, 2] = up / norm
                    need[r, j] = _min(-clear, bound)
                for c in range(3):
                    prev = out[r, t - 1, c]
                    v = _min(_max(plans[r, t, c] - prev, -bound), bound)
                    v += prev
                    q[r, c] = _min(_max(v, lo[r, c]), hi[r, c])
                d0, d1, d2 = q[r, 0] - p0, q[r, 1] - p1, q[r, 2] - p2
                for j in range(k):
                    s = need[r, j] - (nrm[r, j, 0] * d0 + nrm[r, j, 1] * d1 + nrm[r, j, 2] * d2)
                    short[r, j] = s
                    any_short = any_short or s > 0
            pushed = 0
            while pushed < rounds and any_short:
                any_short = False
                for r in range(first, first + group):
                    p0, p1, p2 = out[r, t - 1, 0], out[r, t - 1, 1], out[r, t - 1, 2]
                    for j in range(k):  # every hull's push from the round's q, then added
                        f0, f1, f2 = nrm[r, j, 0], nrm[r, j, 1], nrm[r, j, 2]
                        h0 = (q[r, 0] <= lo[r, 0] and f0 < 0) or (q[r, 0] >= hi[r, 0] and f0 > 0)
                        h1 = (q[r, 1] <= lo[r, 1] and f1 < 0) or (q[r, 1] >= hi[r, 1] and f1 > 0)
                        h2 = (q[r, 2] <= lo[r, 2] and f2 < 0) or (q[r, 2] >= hi[r, 2] and f2 > 0)
                        g0 = 0.0 if h0 else f0
                        g1 = 0.0 if h1 else f1
                        g2 = 0.0 if h2 else f2
                        room = g0 * f0 + g1 * f1 + g2 * f2
                        if not (h0 or h1 or h2):
                            room = 1.0
                        s = short[r, j]
                        size = s / room if (s > 0) and (room > 1e-9) else 0.0
                        push[j, 0], push[j, 1], push[j, 2] = size * g0, size * g1, size * g2
                    for j in range(k):  # hull by hull, as the plain path adds them
                        q[r, 0] += push[j, 0]
                        q[r, 1] += push[j, 1]
                        q[r, 2] += push[j, 2]
                    for c in range(3):
                        q[r, c] = _min(_max(q[r, c], lo[r, c]), hi[r, c])
                    d0, d1, d2 = q[r, 0] - p0, q[r, 1] - p1, q[r, 2] - p2
                    for j in range(k):
                        s = need[r, j] - (nrm[r, j, 0] * d0 + nrm[r, j, 1] * d1 + nrm[r, j, 2] * d2)
                        short[r, j] = s
                        any_short = any_short or s > 0
                pushed += 1
            any_cut = False
            if pushed:
                for r in range(first, first + group):
                    for j in range(k):
                        if need[r, j] <= 0 and short[r, j] > 1e-12:
                            any_cut = True
            for r in range(first, first + group):
                p0, p1, p2 = out[r, t - 1, 0], out[r, t - 1, 1], out[r, t - 1, 2]
                if pushed:
                    d0, d1, d2 = q[r, 0] - p0, q[r, 1] - p1, q[r, 2] - p2
                    big = _max(_max(abs(d0), abs(d1)), abs(d2))
                    scale = _min(1.0, bound / _max(big, 1e-12))
                    if any_cut:
                        frac = 1.0
                        for j in range(k):
                            cut = need[r, j] <= 0 and short[r, j] > 1e-12
                            fj = -need[r, j] / (short[r, j] - need[r, j]) if cut else 1.0
                            frac = fj if j == 0 else _min(frac, fj)
                        scale = _min(scale, frac)
                    q[r, 0] = p0 + d0 * scale
                    q[r, 1] = p1 + d1 * scale
                    q[r, 2] = p2 + d2 * scale
                into = False
                for j in range(k):
                    g0, g1 = q[r, 0] - hulls[j, 0], q[r, 1] - hulls[j, 1]
                    if math.hypot(g0, g1) < hulls[j, 2] and q[r, 2] < hulls[j, 3] and outside[r, j]:
                        into = True
                if into:
                    q[r, 0], q[r, 1], q[r, 2] = p0, p1, p2
                out[r, t, 0], out[r, t, 1], out[r, t, 2] = q[r, 0], q[r, 1], q[r, 2]


@compiled
def walk_turn(turn: np.ndarray, low: np.ndarray, high: np.ndarray, bound: float) -> None:
    """The keep-out walk's first pass (``_keep_out_walk``) on plans (N, T+1, s), in place: roll
    and pitch (columns 3-4, scaled) of each waypoint after x0 into ``low``-``high`` (2,), then
    walked at the step ``bound`` from x0."""
    for r in range(turn.shape[0]):
        for t in range(1, turn.shape[1]):
            for c in range(2):
                turn[r, t, 3 + c] = _min(_max(turn[r, t, 3 + c], low[c]), high[c])
        for t in range(1, turn.shape[1]):
            for c in range(2):
                prev = turn[r, t - 1, 3 + c]
                turn[r, t, 3 + c] = prev + _min(_max(turn[r, t, 3 + c] - prev, -bound), bound)


@compiled
def walk_shell(
    pos: np.ndarray,
    off: np.ndarray,
    shoulder: np.ndarray,
    inner: float,
    radius: float,
    rounds: int,
    hulls: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
) -> None:
    """The keep-out walk's middle pass (``_keep_out_walk``) on plans (N, T+1, s), in place,
    for each waypoint after x0: ``rounds`` times into the shell around ``shoulder`` (the hand
    at the cup's position + ``off`` (N, T, 3)) and the box ``low``-``high`` (3,); out of each
    hull in turn by the shorter way; into the box; lifted over a hull the box put it back in."""
    k = hulls.shape[0]
    for r in range(pos.shape[0]):
        for t in range(1, pos.shape[1]):
            o0, o1, o2 = off[r, t - 1, 0], off[r, t - 1, 1], off[r, t - 1, 2]
            x, y, z = pos[r, t, 0], pos[r, t, 1], pos[r, t, 2]
            for _ in range(rounds):
                a0 = (x + o0) - shoulder[0]
                a1 = (y + o1) - shoulder[1]
                a2 = (z + o2) - shoulder[2]
                far = _max(math.sqrt((a0 * a0 + a1 * a1) + a2 * a2), 1e-12)
                m = _min(_max(1.0, inner / far), radius / far)
                x = _min(_max((shoulder[0] - o0) + a0 * m, low[0]), high[0])
                y = _min(_max((shoulder[1] - o1) + a1 * m, low[1]), high[1])
                z = _min(_max((shoulder[2] - o2) + a2 * m, low[2]), high[2])
            for j in range(k):
                cx, cy, rad, top = hulls[j, 0], hulls[j, 1], hulls[j, 2], hulls[j, 3]
                dx, dy = x - cx, y - cy
                rho = _max(math.hypot(dx, dy), 1e-12)
                side, lift = rad - rho, top - z
                if side > 0 and lift > 0:
                    if side < lift:
                        grow = rad / rho
                        x, y = cx + dx * grow, cy + dy * grow
                    else:
                        z = top
            x = _min(_max(x, low[0]), high[0])
            y = _min(_max(y, low[1]), high[1])
            z = _min(_max(z, low[2]), high[2])
            for j in range(k):
                if math.hypot(x - hulls[j, 0], y - hulls[j, 1]) < hulls[j, 2] and z < hulls[j, 3]:
                    z = hulls[j, 3]
            pos[r, t, 0], pos[r, t, 1], pos[r, t, 2] = x, y, z


__all__ = ["walk_out", "walk_shell", "walk_turn"]
