"""Eq. M6's candidate search for the Robot and Highway Tasks as compiled loops (numba, through
``strol_gym.compiled``): one pass over each person's candidates, no (B, K) temporaries.

Each loop repeats, number for number, the IEEE operations of the plain path (``RobotTask.g_planes``
or ``HighwayTask.g`` followed by ``strol_gym.humans.choices.optimal_correction``), in the same
order and without fast-math, so it picks the same candidate to the bit (tests/test_compiled.py).
Sine and cosine are the C library's in both paths; numpy's tangent and arctangent are its own
(SIMD) ones, so the Highway's steering angle β = arctan(½ tan δ) comes in computed by numpy.

Beside the searches: the candidates' scaling (``unit_to_box``) and the Highway's φ of one
state (``highway_phi``), the same operations as their plain paths in one compiled call each.
"""

from __future__ import annotations

import math

import numpy as np

from strol_gym.compiled import compiled


@compiled
def unit_to_box(u: np.ndarray, scale: np.ndarray) -> None:
    """``Task._unit_to_box`` (u (n, k, a), any strides; ``scale`` a bound per axis): U·2 + (−1),
    then times the axis' bound, rounded after each operation as numpy's three passes round
    them (the first is exact)."""
    for i in range(u.shape[0]):
        for j in range(u.shape[1]):
            for c in range(u.shape[2]):
                v = u[i, j, c] * 2.0
                v = v + -1.0
                u[i, j, c] = v * scale[c]


@compiled
def _argmin_first(norm: float, k: int, best: int, best_norm: float) -> tuple[int, float, bool]:
    """One step of numpy's argmin (from pick 0 at +inf): the first minimum, or the first NaN
    (which ends the search)."""
    if norm != norm:
        return k, norm, True
    if norm < best_norm:
        return k, norm, False
    return best, best_norm, False


@compiled
def robot_m6(
    x: np.ndarray,
    u_r: np.ndarray,
    th_hat: np.ndarray,
    th_star: np.ndarray,
    cand: np.ndarray,
    alpha: float,
    plate: np.ndarray,
    cup: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    best: np.ndarray,
) -> None:
    """Eq. M6 on ``RobotTask``: the index of each person's chosen candidate, into ``best`` (B,)."""
    for b in range(cand.shape[0]):
        best[b] = _robot_pick(
            x[b], u_r[b], th_hat[b], th_star[b], cand[b], alpha, plate, cup, lo, hi
        )


@compiled
def robot_m6_drawn(
    x: np.ndarray,
    u_r: np.ndarray,
    th_hat: np.ndarray,
    th_star: np.ndarray,
    units: np.ndarray,
    noise: np.ndarray,
    prm: np.ndarray,
    out: np.ndarray,
) -> None:
    """A nominal person's whole correction on ``RobotTask`` from their draws, into ``out`` (B, 3):
    the candidates from the uniform draws ``units`` (B, K, 3) as ``Task._unit_to_box`` scales
    them (zero first), eq. M6's pick (``robot_m6``) and the noise ``perturb`` adds,
    (u + ε a) + (σ a) z. ``prm``: α, σ, ε, then 3 numbers each: the plate, the cup, the box's
    low and high corners, the candidates' bound per axis and a_max."""
    alpha, sigma, bias = prm[0], prm[1], prm[2]
    plate, cup, lo, hi = prm[3:6], prm[6:9], prm[9:12], prm[12:15]
    scale, a_max = prm[15:18], prm[18:21]
    cand = np.empty((units.shape[1] + 1, 3))
    for b in range(units.shape[0]):
        for c in range(3):
            cand[0, c] = 0.0
        for k in range(units.shape[1]):
            for c in range(3):
                v = units[b, k, c] * 2.0
                v = v + -1.0
                cand[k + 1, c] = v * scale[c]
        pick = _robot_pick(x[b], u_r[b], th_hat[b], th_star[b], cand, alpha, plate, cup, lo, hi)
        for c in range(3):
            out[b, c] = (cand[pick, c] + bias * a_max[c]) + (sigma * a_max[c]) * noise[b, c]


@compiled
def _robot_pick(
    x: np.ndarray,
    u_r: np.ndarray,
    th_hat: np.ndarray,
    th_star: np.ndarray,
    cand: np.ndarray,
    alpha: float,
    plate: np.ndarray,
    cup: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
) -> int:
    """Eq. M6 for one person (x, u_R, θ̂, θ* rows; candidates (K, 3)): the chosen index."""
    p0, p1 = plate[0], plate[1]
    c0, c1, c2 = cup[0], cup[1], cup[2]
    base = np.empty(3)
    xr = np.empty(3)
    for a in range(3):
        base[a] = x[a] + u_r[a]
        v = base[a] + 0.0
        v = lo[a] if v < lo[a] else v
        xr[a] = hi[a] if v > hi[a] else v
    d0, d1 = p0 - xr[0], p1 - xr[1]
    e0, e1, e2 = c0 - xr[0], c1 - xr[1], c2 - xr[2]
    phi0 = -math.sqrt(d0 * d0 + d1 * d1)
    phi1 = -math.sqrt((e0 * e0 + e2 * e2) + e1 * e1)
    h0, h1, s0, s1 = th_hat[0], th_hat[1], th_star[0], th_star[1]
    pick, low = 0, math.inf
    for k in range(cand.shape[0]):
        xh0 = base[0] + cand[k, 0]
        xh1 = base[1] + cand[k, 1]
        xh2 = base[2] + cand[k, 2]
        xh0 = lo[0] if xh0 < lo[0] else xh0
        xh1 = lo[1] if xh1 < lo[1] else xh1
        xh2 = lo[2] if xh2 < lo[2] else xh2
        xh0 = hi[0] if xh0 > hi[0] else xh0
        xh1 = hi[1] if xh1 > hi[1] else xh1
        xh2 = hi[2] if xh2 > hi[2] else xh2
        d0, d1 = p0 - xh0, p1 - xh1
        e0, e1, e2 = c0 - xh0, c1 - xh1, c2 - xh2
        g0 = -math.sqrt(d0 * d0 + d1 * d1) - phi0
        g1 = -math.sqrt((e0 * e0 + e2 * e2) + e1 * e1) - phi1
        r0 = s0 - (g0 * alpha + h0)
        r1 = s1 - (g1 * alpha + h1)
        norm = r0 * r0 + r1 * r1
        pick, low, stop = _argmin_first(norm, k, pick, low)
        if stop:
            break
    return pick


@compiled
def _robot_ahead(xr: float, yr: float, vr: float, hr: float, t: float) -> tuple[float, float]:
    """The robot car's position ``headway`` seconds ahead, as ``HighwayTask._phi`` computes it
    (once per person here: it does not depend on the candidate)."""
    return xr + t * vr * math.cos(hr), yr + t * vr * math.sin(hr)


@compiled
def _phi(
    ahead: tuple[float, float],
    xh: float,
    yh: float,
    vh: float,
    hh: float,
    prm: np.ndarray,
) -> tuple[float, float, float]:
    """``HighwayTask._phi`` of one pair of cars, the robot's part ``ahead`` (``_robot_ahead``);
    ``prm`` as ``HighwayTask._kernel_params``."""
    t, min_gap, close, lane_w = prm[0], prm[1], prm[2], prm[3]
    lane0, lane_width, gap_scale, speed_ref, speed_scale = prm[4], prm[5], prm[6], prm[7], prm[8]
    vh_sin = vh * math.sin(hh)
    behind = ahead[0] - (xh + t * vh * math.cos(hh))
    beside = ahead[1] - (yh + t * vh_sin)
    short = min_gap - behind
    a, c = -short, close * short
    slot = (a if a >= c else c) + lane_w * abs(beside)
    lane = (yh + t * vh_sin - lane0) / lane_width
    return slot / -gap_scale, (vh - speed_ref) / speed_scale, 1.0 - abs(lane - 1.0)


@compiled
def highway_phi(x: np.ndarray, prm: np.ndarray) -> tuple[float, float, float]:
    """``HighwayTask.features`` of one state x (8,); ``prm`` as ``HighwayTask._kernel_params``."""
    return _phi(_robot_ahead(x[0], x[1], x[2], x[3], prm[0]), x[4], x[5], x[6], x[7], prm)


@compiled
def _car(
    px: float,
    py: float,
    v: float,
    h: float,
    acc: float,
    beta: float,
    dt: float,
    half_length: float,
    max_speed: float,
    min_speed: float,
) -> tuple[float, float, float, float]:
    """``strol_gym.tasks.highway._car_step`` of one car, its steering angle β given."""
    if v > max_speed:
        acc = min(acc, max_speed - v)
    elif v < min_speed:
        acc = max(acc, min_speed - v)
    hb = h + beta
    return (
        px + v * math.cos(hb) * dt,
        py + v * math.sin(hb) * dt,
        v + acc * dt,
        h + v * math.sin(beta) / half_length * dt,
    )


_BOUND = 1e15
"""Magnitude below which every input of ``highway_m6`` keeps its intermediates finite (and
above whose inverse its divisors stay): then no candidate's norm can be NaN, which lets the
search skip a candidate by its speed term alone (``_finite_people``)."""


@compiled
def _bounded(v: float) -> bool:
    """|v| <= ``_BOUND`` (False for NaN)."""
    return abs(v) <= _BOUND


@compiled
def _params_bounded(prm: np.ndarray) -> bool:
    """Every parameter bounded, and the divisors (lane width, gap and speed scales, half the car
    length) at least 1 / ``_BOUND`` in magnitude."""
    for i in range(prm.shape[0]):
        if not _bounded(prm[i]):
            return False
    for i in (5, 6, 8, 11):
        if not abs(prm[i]) >= 1.0 / _BOUND:
            return False
    return True


@compiled
def highway_m6(
    x: np.ndarray,
    acc_r: np.ndarray,
    beta_r: np.ndarray,
    th_hat: np.ndarray,
    th_star: np.ndarray,
    cand: np.ndarray,
    beta_h: np.ndarray,
    prm: np.ndarray,
    best: np.ndarray,
) -> None:
    """Eq. M6 on ``HighwayTask``: each person's chosen candidate index into ``best`` (B,).
    ``acc_r``, ``beta_r``: the robot's (B,) acceleration and steering angle β; ``cand``: the
    candidates (B, K, 2) (their accelerations read in place), ``beta_h`` their β (B, K);
    ``prm`` as ``HighwayTask._kernel_params``.

    A candidate whose speed term alone, q1², is already at least the best norm so far cannot be
    picked: the norm (q0² + q1²) + q2² of nonnegative squares rounds to no less than q1², and
    numpy's argmin takes the first of equal minima. So its sines and cosines (five, most of the
    cost) are skipped. That holds unless its norm would be NaN (where argmin stops), which
    bounded inputs rule out: the skip runs only for a person whose numbers and this candidate's
    are all within ``_BOUND`` (``_bounded``), the same pick to the bit."""
    alpha, dt, half, vmax, vmin = prm[9], prm[10], prm[11], prm[12], prm[13]
    speed_ref, speed_scale = prm[7], prm[8]
    params_ok = _params_bounded(prm)
    for b in range(beta_h.shape[0]):
        r = _car(x[b, 0], x[b, 1], x[b, 2], x[b, 3], acc_r[b], beta_r[b], dt, half, vmax, vmin)
        z = _car(x[b, 4], x[b, 5], x[b, 6], x[b, 7], 0.0, 0.0, dt, half, vmax, vmin)
        ahead = _robot_ahead(r[0], r[1], r[2], r[3], prm[0])
        f0 = _phi(ahead, z[0], z[1], z[2], z[3], prm)
        h0, h1, h2 = th_hat[b, 0], th_hat[b, 1], th_hat[b, 2]
        s0, s1, s2 = th_star[b, 0], th_star[b, 1], th_star[b, 2]
        may_skip = params_ok and _bounded(acc_r[b]) and _bounded(beta_r[b])
        for i in range(8):
            may_skip = may_skip and _bounded(x[b, i])
        for i in range(3):
            may_skip = may_skip and _bounded(th_hat[b, i]) and _bounded(th_star[b, i])
        v = x[b, 6]
        pick, low = 0, math.inf
        for k in range(beta_h.shape[1]):
            if may_skip and _bounded(cand[b, k, 0]) and _bounded(beta_h[b, k]):
                # The speed term as ``_car`` and ``_phi`` compute it (the same operations).
                acc = cand[b, k, 0]
                if v > vmax:
                    acc = min(acc, vmax - v)
                elif v < vmin:
                    acc = max(acc, vmin - v)
                q1 = s1 - ((((v + acc * dt) - speed_ref) / speed_scale - f0[1]) * alpha + h1)
                if q1 * q1 >= low:
                    continue
            c = _car(
                x[b, 4],
                x[b, 5],
                x[b, 6],
                x[b, 7],
                cand[b, k, 0],
                beta_h[b, k],
                dt,
                half,
                vmax,
                vmin,
            )
            f = _phi(ahead, c[0], c[1], c[2], c[3], prm)
            q0 = s0 - ((f[0] - f0[0]) * alpha + h0)
            q1 = s1 - ((f[1] - f0[1]) * alpha + h1)
            q2 = s2 - ((f[2] - f0[2]) * alpha + h2)
            norm = q0 * q0 + q1 * q1 + q2 * q2
            pick, low, stop = _argmin_first(norm, k, pick, low)
            if stop:
                break
        best[b] = pick
