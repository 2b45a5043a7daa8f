"""Eq. M6's candidate search for the Robot and Highway Tasks as compiled loops (numba, through
``strol_gym.compiled``): one pass over each person's candidates, no (B, K) temporaries.

Each search repeats, number for number, the IEEE operations of the plain path
(``RobotTask.g_planes`` or ``HighwayTask.g`` followed by
``strol_gym.humans.choices.optimal_correction``), in the same order and without fast-math, so
it picks the same candidate to the bit (tests/test_compiled.py). Sine and cosine are the C
library's in both paths; numpy's tangent and arctangent are its own (SIMD) ones, so the
Highway's steering angles β = arctan(½ tan δ) come in computed by numpy. On the Highway a
screen first drops, with polynomials in place of the trigonometry and a proven error bound,
the candidates that cannot be picked (``highway_m6_screen``); the exact search runs on the rest.

A nominal person's whole correction from their draws (the candidates' scaling, the search and
the noise) runs as one call where the search allows it: ``robot_m6_drawn``, and
``highway_m6_drawn`` for the people the Highway's screen settles alone.

Beside the searches: the candidates' scaling (``unit_to_box``), the Highway's φ of one state
(``highway_phi``) and the Robot's of many (``robot_features``), the same operations as their
plain paths in one compiled call each.
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
def robot_features(x: np.ndarray, objects: np.ndarray, out: np.ndarray) -> None:
    """``RobotTask.features`` of states ``x`` (B, 3) into ``out`` (B, 2), ``objects`` the plate
    and the cup (2, 3): the operations of ``RobotTask._features_one`` per state."""
    p0, p1 = objects[0, 0], objects[0, 1]
    c0, c1, c2 = objects[1, 0], objects[1, 1], objects[1, 2]
    for b in range(x.shape[0]):
        d0, d1 = p0 - x[b, 0], p1 - x[b, 1]
        e0, e1, e2 = c0 - x[b, 0], c1 - x[b, 1], c2 - x[b, 2]
        out[b, 0] = -math.sqrt(d0 * d0 + d1 * d1)
        out[b, 1] = -math.sqrt((e0 * e0 + e2 * e2) + e1 * e1)


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
    k = cand.shape[1]
    by_axis, norms = np.empty((3, k)), np.empty(k)
    for b in range(cand.shape[0]):
        for j in range(k):
            for c in range(3):
                by_axis[c, j] = cand[b, j, c]
        best[b] = _robot_pick(
            x[b], u_r[b], th_hat[b], th_star[b], by_axis, alpha, plate, cup, lo, hi, norms
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
    k = units.shape[1] + 1
    cand, norms = np.empty((3, k)), np.empty(k)
    for b in range(units.shape[0]):
        for c in range(3):
            cand[c, 0] = 0.0
            s = scale[c]
            for j in range(1, k):
                v = units[b, j - 1, c] * 2.0
                v = v + -1.0
                cand[c, j] = v * s
        pick = _robot_pick(
            x[b], u_r[b], th_hat[b], th_star[b], cand, alpha, plate, cup, lo, hi, norms
        )
        for c in range(3):
            out[b, c] = (cand[c, pick] + bias * a_max[c]) + (sigma * a_max[c]) * noise[b, c]


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
    norms: np.ndarray,
) -> int:
    """Eq. M6 for one person (x, u_R, θ̂, θ* rows; candidates by axis (3, K)): the chosen index.
    Every candidate's norm first, into ``norms`` (K,), in one loop the compiler runs several
    candidates at a time (its square roots too); then numpy's argmin over them."""
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
    b0, b1, b2 = base[0], base[1], base[2]
    lo0, lo1, lo2, hi0, hi1, hi2 = lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    k = cand.shape[1]
    for j in range(k):
        xh0 = b0 + cand[0, j]
        xh1 = b1 + cand[1, j]
        xh2 = b2 + cand[2, j]
        xh0 = lo0 if xh0 < lo0 else xh0
        xh1 = lo1 if xh1 < lo1 else xh1
        xh2 = lo2 if xh2 < lo2 else xh2
        xh0 = hi0 if xh0 > hi0 else xh0
        xh1 = hi1 if xh1 > hi1 else xh1
        xh2 = hi2 if xh2 > hi2 else xh2
        d0, d1 = p0 - xh0, p1 - xh1
        e0, e1, e2 = c0 - xh0, c1 - xh1, c2 - xh2
        g0 = -math.sqrt(d0 * d0 + d1 * d1) - phi0
        g1 = -math.sqrt((e0 * e0 + e2 * e2) + e1 * e1) - phi1
        r0 = s0 - (g0 * alpha + h0)
        r1 = s1 - (g1 * alpha + h1)
        norms[j] = r0 * r0 + r1 * r1
    pick, low = 0, math.inf
    for j in range(k):
        pick, low, stop = _argmin_first(norms[j], j, pick, low)
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
"""Magnitude below which every input of the Highway's search keeps its intermediates finite
(and above whose inverse its divisors stay): then no candidate's norm can be NaN (where
numpy's argmin stops), which lets ``highway_m6_screen`` drop candidates."""


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


# ---------------------------------------------------------------- the Highway's screened search
_SMALL_STEER = 0.05
"""|δ| up to which ``_slip_near`` follows the steering angle β = arctan(½ tan δ) to ~1e-17."""
_SMALL_ANGLE = 0.5
"""|angle| up to which ``_sin_near`` and ``_cos_near`` follow sine and cosine to ~1e-14."""
_SLACK = 1e-10
"""The screen's error allowance relative to the sizes it works with (``_screen_error``): at
least a hundred times the worst gap between its approximations and the exact search's numbers
(series truncation ~1e-14 and rounding ~1e-16, times the same sizes)."""


@compiled
def _sin_near(a: float) -> float:
    """sin a for |a| <= ``_SMALL_ANGLE`` by its Taylor series to a¹¹ (truncation < 2e-14)."""
    s = a * a
    return a * (
        1.0
        + s
        * (
            -1.0 / 6
            + s * (1.0 / 120 + s * (-1.0 / 5040 + s * (1.0 / 362880 + s * (-1.0 / 39916800))))
        )
    )


@compiled
def _cos_near(a: float) -> float:
    """cos a for |a| <= ``_SMALL_ANGLE`` by its Taylor series to a¹² (truncation < 1e-15)."""
    s = a * a
    return 1.0 + s * (
        -0.5
        + s
        * (
            1.0 / 24
            + s * (-1.0 / 720 + s * (1.0 / 40320 + s * (-1.0 / 3628800 + s * (1.0 / 479001600))))
        )
    )


@compiled
def _slip_near(d: float) -> float:
    """β = arctan(½ tan δ) for |δ| <= ``_SMALL_STEER`` by the two Taylor series (tan to δ⁹,
    arctan to y⁹; truncation < 1e-16)."""
    s = d * d
    t = d * (1.0 + s * (1.0 / 3 + s * (2.0 / 15 + s * (17.0 / 315 + s * (62.0 / 2835)))))
    y = 0.5 * t
    q = y * y
    return y * (1.0 + q * (-1.0 / 3 + q * (1.0 / 5 + q * (-1.0 / 7 + q * (1.0 / 9)))))


@compiled
def _screen_error(
    x: np.ndarray,
    b: int,
    ahead: tuple[float, float],
    f0: tuple[float, float, float],
    th_hat: np.ndarray,
    th_star: np.ndarray,
    prm: np.ndarray,
    acc_robot: float,
    acc_bound: float,
) -> float:
    """A bound on how far, in each term of eq. M6's residual θ* − (θ̂ + α g), the screen's
    numbers may be from the exact search's for person b (the robot's acceleration
    ``acc_robot``, candidates' |acceleration| up to ``acc_bound``): ``_SLACK`` times
    (sensitivity of a term to positions) times (the sizes of the positions, speeds and their
    steps it is computed from, the robot car's included: its β is screened too)."""
    t, close, lane_w, lane_width, gap_scale = prm[0], prm[2], prm[3], prm[5], prm[6]
    alpha, dt, half = prm[9], prm[10], prm[11]
    speed = abs(x[b, 6]) + acc_bound * abs(dt)
    speed_r = abs(x[b, 2]) + abs(acc_robot) * abs(dt)
    reach = abs(dt) + abs(t)
    sizes = (
        1.0
        + abs(x[b, 0])
        + abs(x[b, 1])
        + abs(x[b, 3])
        + speed_r * reach * (1.0 + reach / abs(half))
        + abs(x[b, 4])
        + abs(x[b, 5])
        + abs(x[b, 7])
        + abs(ahead[0])
        + abs(ahead[1])
        + abs(prm[1])
        + abs(prm[4])
        + abs(prm[7])
        + speed * reach * (1.0 + reach / abs(half))
    )
    gain = (1.0 + abs(alpha)) * (1.0 + max(1.0, abs(close)) + abs(lane_w))
    gain *= 1.0 + 1.0 / abs(gap_scale) + 1.0 / abs(lane_width)
    weights = 1.0
    for i in range(3):
        weights += abs(th_hat[b, i]) + abs(th_star[b, i]) + abs(alpha) * abs(f0[i])
    return _SLACK * gain * sizes * weights


@compiled
def highway_m6_screen(
    x: np.ndarray,
    u_r: np.ndarray,
    th_hat: np.ndarray,
    th_star: np.ndarray,
    cand: np.ndarray,
    prm: np.ndarray,
    keep: np.ndarray,
    steer: np.ndarray,
    best: np.ndarray,
) -> int:
    """Eq. M6's choice where a screen settles it, and what the exact search
    (``highway_m6_kept``) must still look at elsewhere. ``u_r`` (B, 2): the robot's actions.
    A person whose screen keeps one candidate has it as ``best[b]``; for each other person
    ``best[b]`` = −1, ``keep[b]`` marks the candidates kept and ``steer`` gets, packed in
    order, the robot's steering angle δ and then the kept candidates' (numpy turns them into
    β = arctan(½ tan δ) in one call). Returns how many angles were packed.

    The screen computes each candidate's eq. M6 norm with Taylor polynomials in place of the
    sines, cosines, tangent and arctangent (``_sin_near``, ``_cos_near``, ``_slip_near``, the
    robot car's β too) and products by reciprocals in place of divisions, each residual term
    within a proven error E of the exact one (``_screen_error``). A candidate whose screened
    distance ‖·‖ exceeds the smallest screened distance by more than 4E (and a relative 1e-12
    for the rounding of norms, roots and squares) has a norm larger than another candidate's:
    it cannot be numpy's argmin, the first minimum, so it is dropped; one left is the
    minimum. Kept: every candidate of a person with an unbounded or NaN input (where a norm
    could be NaN) or a robot's |δ| above ``_SMALL_STEER``, and every candidate outside the
    polynomials' ranges (|δ| <= ``_SMALL_STEER``, angles <= ``_SMALL_ANGLE``)."""
    alpha, dt, half, vmax, vmin = prm[9], prm[10], prm[11], prm[12], prm[13]
    t, min_gap, close, lane_w = prm[0], prm[1], prm[2], prm[3]
    lane0, lane_width, gap_scale, speed_ref, speed_scale = prm[4], prm[5], prm[6], prm[7], prm[8]
    to_lane, to_gap, to_speed = 1.0 / lane_width, -1.0 / gap_scale, 1.0 / speed_scale
    params_ok = _params_bounded(prm)
    n_cand = cand.shape[1]
    acc_k = np.empty(n_cand)
    steer_k = np.empty(n_cand)
    norm_k = np.empty(n_cand)
    hb_k = np.empty(n_cand)
    sin_beta_k = np.empty(n_cand)
    n = 0
    for b in range(cand.shape[0]):
        acc_r, steer_r = u_r[b, 0], u_r[b, 1]
        may_screen = params_ok and _bounded(acc_r) and abs(steer_r) <= _SMALL_STEER
        for i in range(8):
            may_screen = may_screen and _bounded(x[b, i])
        for i in range(3):
            may_screen = may_screen and _bounded(th_hat[b, i]) and _bounded(th_star[b, i])
        acc_bound = 0.0
        for k in range(n_cand):
            acc_k[k] = cand[b, k, 0]
            steer_k[k] = cand[b, k, 1]
            a = abs(acc_k[k])
            may_screen = may_screen and _bounded(a) and _bounded(steer_k[k])
            acc_bound = a if a > acc_bound else acc_bound
        cut = math.inf
        if may_screen:
            beta_r = _slip_near(steer_r)
            r = _car(x[b, 0], x[b, 1], x[b, 2], x[b, 3], acc_r, beta_r, dt, half, vmax, vmin)
            z = _car(x[b, 4], x[b, 5], x[b, 6], x[b, 7], 0.0, 0.0, dt, half, vmax, vmin)
            ahead = _robot_ahead(r[0], r[1], r[2], r[3], prm[0])
            f0 = _phi(ahead, z[0], z[1], z[2], z[3], prm)
            err = _screen_error(x, b, ahead, f0, th_hat, th_star, prm, acc_r, acc_bound)
            px, py, v, h = x[b, 4], x[b, 5], x[b, 6], x[b, 7]
            v_dt, turn = v * dt, v / half * dt
            # _car's speed clip, as bounds on the acceleration (none within the limits)
            acc_hi = vmax - v if v > vmax else math.inf
            acc_lo = vmin - v if v < vmin and not v > vmax else -math.inf
            h0, h1, h2 = th_hat[b, 0], th_hat[b, 1], th_hat[b, 2]
            s0, s1, s2 = th_star[b, 0], th_star[b, 1], th_star[b, 2]
            g0, g1, g2 = f0[0], f0[1], f0[2]
            # the polynomials first, in a loop of their own: its iterations are short and
            # independent, so the processor overlaps their long chains of products
            for k in range(n_cand):
                beta = _slip_near(steer_k[k])
                hb_k[k] = h + beta
                sin_beta_k[k] = _sin_near(beta)
            for k in range(n_cand):
                d = steer_k[k]
                hb = hb_k[k]
                xh = px + v_dt * _cos_near(hb)
                yh = py + v_dt * _sin_near(hb)
                vh = v + min(max(acc_k[k], acc_lo), acc_hi) * dt
                hh = h + sin_beta_k[k] * turn
                vh_sin = vh * _sin_near(hh)
                behind = ahead[0] - (xh + t * vh * _cos_near(hh))
                beside = ahead[1] - (yh + t * vh_sin)
                short = min_gap - behind
                slot = max(-short, close * short) + lane_w * abs(beside)
                lane = (yh + t * vh_sin - lane0) * to_lane
                q0 = s0 - ((slot * to_gap - g0) * alpha + h0)
                q1 = s1 - (((vh - speed_ref) * to_speed - g1) * alpha + h1)
                q2 = s2 - (((1.0 - abs(lane - 1.0)) - g2) * alpha + h2)
                # (& rather than and: no branch in the loop, which the compiler then vectorises)
                inside = (abs(d) <= _SMALL_STEER) & (abs(hb) <= _SMALL_ANGLE)
                inside = inside & (abs(hh) <= _SMALL_ANGLE)
                norm_k[k] = q0 * q0 + q1 * q1 + q2 * q2 if inside else math.inf
            low = math.inf
            for k in range(n_cand):
                low = norm_k[k] if norm_k[k] < low else low
            if low < math.inf:
                # beyond this, a screened candidate is farther than the nearest, exactly too
                cut = (math.sqrt(low) * (1.0 + 1e-12) + 4.0 * err) * (1.0 + 2e-12)
                cut = cut * cut * (1.0 + 1e-12)
        count, last = 0, 0
        for k in range(n_cand):
            # kept: near the nearest, outside the polynomials' ranges (inf) or NaN
            kept = cut == math.inf or not norm_k[k] > cut or norm_k[k] == math.inf
            keep[b, k] = kept
            if kept:
                count, last = count + 1, k
        if count == 1 and cut < math.inf:
            best[b] = last  # every other candidate's norm is larger
            continue
        best[b] = -1
        steer[n] = steer_r
        n += 1
        for k in range(n_cand):
            if keep[b, k]:
                steer[n] = steer_k[k]
                n += 1
    return n


@compiled
def highway_m6_kept(
    x: np.ndarray,
    u_r: np.ndarray,
    th_hat: np.ndarray,
    th_star: np.ndarray,
    cand: np.ndarray,
    keep: np.ndarray,
    beta: np.ndarray,
    prm: np.ndarray,
    best: np.ndarray,
) -> None:
    """Eq. M6 for the people ``highway_m6_screen`` left open (``best[b]`` = −1): the first
    minimum of the norm (or first NaN) among the candidates ``keep`` marks, into ``best``,
    the numbers of ``HighwayTask.g``. ``beta``: the steering angles β the screen packed (per
    open person, the robot car's and then the kept candidates')."""
    alpha, dt, half, vmax, vmin = prm[9], prm[10], prm[11], prm[12], prm[13]
    j = 0
    for b in range(cand.shape[0]):
        if best[b] >= 0:
            continue
        r = _car(x[b, 0], x[b, 1], x[b, 2], x[b, 3], u_r[b, 0], beta[j], dt, half, vmax, vmin)
        j += 1
        z = _car(x[b, 4], x[b, 5], x[b, 6], x[b, 7], 0.0, 0.0, dt, half, vmax, vmin)
        ahead = _robot_ahead(r[0], r[1], r[2], r[3], prm[0])
        f0 = _phi(ahead, z[0], z[1], z[2], z[3], prm)
        h0, h1, h2 = th_hat[b, 0], th_hat[b, 1], th_hat[b, 2]
        s0, s1, s2 = th_star[b, 0], th_star[b, 1], th_star[b, 2]
        pick, low, stop = 0, math.inf, False
        for k in range(cand.shape[1]):
            if not keep[b, k]:
                continue
            beta_h = beta[j]
            j += 1
            if stop:
                continue
            c = _car(
                x[b, 4], x[b, 5], x[b, 6], x[b, 7], cand[b, k, 0], beta_h, dt, half, vmax, vmin
            )
            f = _phi(ahead, c[0], c[1], c[2], c[3], prm)
            q0 = s0 - ((f[0] - f0[0]) * alpha + h0)
            q1 = s1 - ((f[1] - f0[1]) * alpha + h1)
            q2 = s2 - ((f[2] - f0[2]) * alpha + h2)
            norm = q0 * q0 + q1 * q1 + q2 * q2
            pick, low, stop = _argmin_first(norm, k, pick, low)
        best[b] = pick


@compiled
def highway_m6_drawn(
    x: np.ndarray,
    u_r: np.ndarray,
    th_hat: np.ndarray,
    th_star: np.ndarray,
    units: np.ndarray,
    noise: np.ndarray,
    prm: np.ndarray,
    cand: np.ndarray,
    keep: np.ndarray,
    steer: np.ndarray,
    best: np.ndarray,
    out: np.ndarray,
) -> int:
    """A nominal person's whole correction on ``HighwayTask`` from their draws, where the screen
    settles eq. M6 alone: the candidates from the uniform draws ``units`` (B, K, 2) as
    ``Task._unit_to_box`` scales them (zero first) into ``cand`` (B, K + 1, 2), the screen of
    ``highway_m6_screen`` and, for each person it settles (``best[b]`` >= 0), the noise
    ``perturb`` adds, (u + ε a) + (σ a) z, into ``out`` (B, 2). The other people get
    ``best[b]`` = −1 and are left to the exact search (``highway_m6_kept``, with the screen's
    ``keep`` (B, K + 1) and ``steer`` (B (K + 2)) as ``highway_m6_screen`` fills them). Returns
    how many steering angles it packed (0: everyone settled). ``prm``:
    ``HighwayTask._kernel_params``, then σ, ε, the candidates' bound per axis and a_max."""
    n_prm = prm.shape[0] - 6
    sigma, bias = prm[n_prm], prm[n_prm + 1]
    scale, a_max = prm[n_prm + 2 : n_prm + 4], prm[n_prm + 4 : n_prm + 6]
    b_count, k_count = units.shape[0], units.shape[1]
    for b in range(b_count):
        for c in range(2):
            cand[b, 0, c] = 0.0
        for k in range(k_count):
            for c in range(2):
                v = units[b, k, c] * 2.0
                v = v + -1.0
                cand[b, k + 1, c] = v * scale[c]
    n = highway_m6_screen(x, u_r, th_hat, th_star, cand, prm[:n_prm], keep, steer, best)
    for b in range(b_count):
        pick = best[b]
        if pick < 0:
            continue
        for c in range(2):
            out[b, c] = (cand[b, pick, c] + bias * a_max[c]) + (sigma * a_max[c]) * noise[b, c]
    return n
