"""The Highway setting: a human car behind a robot car on a two-lane highway (highway-env frame).

Frame and units are highway-env's: x (m) along the road, y (m) across it, positive to the
driver's *right*; the left lane's centre is y = 0 and the right lane's is y = 4 (lane width 4 m).
Heading h (rad) is measured from the +x axis, positive turning right; speed v in m/s.

State x = (x_R, y_R, v_R, h_R, x_H, y_H, v_H, h_H): the robot car, then the human car.
Action u = (acceleration m/s², front-wheel steering rad) for either car.

The transition f(x, u_H, u_R) is one policy step (``dt`` seconds, a single integration step,
i.e. highway-env's simulation frequency equals its policy frequency) of highway-env's kinematic
bicycle model, ``highway_env.vehicle.kinematics.Vehicle.step``, for both cars, written once and
batched. The env drives both cars with highway-env's own vehicles; a test checks the two agree.

Features φ(x), each divided by a documented scale so values are O(1). T = ``headway`` = 2 s is a
look-ahead at constant velocity (each car keeps its current speed and heading), so that one
step's acceleration or steering shows in φ; "T ahead" below means at that predicted position.

- ``gap`` = −[ max(b − d_min, k (d_min − b)) + κ |a| ] / 20 m: how far the human car is from the
  *tailgating slot* d_min = 10 m (two car lengths, centre to centre) behind the robot car in its
  lane, T ahead. b = x_R − x_H is how far the human is behind (signed: negative once it has
  passed), a = y_R − y_H how far it is beside; k = 4 makes closer than d_min (and passing) cost
  four times as much per metre as farther, κ = 2 makes a metre sideways cost two metres. 0 at
  the slot, about −0.25 ... −1.5 at the start (15–40 m behind).
- ``speed`` = (v_H − 25 m/s) / 5 m/s, the *human* car's speed. The paper names the robot car's
  speed, but u_H cannot change the robot's speed, so g's speed component would always be 0; the
  human's own speed is what its acceleration shows.
- ``lane_change`` = 1 − |ℓ − 1|, ℓ = (y_H + T v_H sin h_H) / 4 m the human car's lateral
  position T ahead in lanes (0 = left lane centre, 1 = right lane centre): it rises as the car
  heads into the right lane and falls beyond that lane's centre (leaving the road is not a
  lane change). Its heading is what moves it within a step, as the paper's "heading direction
  indicating whether the human will change lane".

Prior modes over (gap, speed, lane_change) (the authors' released code gives "tailgate"
(1.0, 1.0, 0.1) and "pass on the right" (0.1, −1.0, 1.0), in *their* feature signs): "tailgate"
(1.0, 1.0, 0.1) keeps its lane and closes in to the slot; "pass on the right" (0.1, 1.0, 1.0)
ignores the gap, prefers speed and changes lane, as the paper's text describes. The speed sign
of the passer is flipped because our speed feature is the human's own speed: with −1.0 a
θ*-maximising driver brakes towards a standstill instead of passing (docs/highway.md).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from typing import ClassVar

import numpy as np

from strol_gym.compiled import use_fast
from strol_gym.priors import MixturePrior, Prior
from strol_gym.tasks.base import Task, positive_field, vector_arg
from strol_gym.tasks.driver import driver_correction

HIGHWAY_MODES = np.array([[1.0, 1.0, 0.1], [0.1, 1.0, 1.0]])
"""Prior modes over (gap, speed, lane_change): "tailgate" and "pass on the right"."""

# highway-env's Vehicle constants (highway_env.vehicle.kinematics.Vehicle); a test checks them.
CAR_LENGTH = 5.0
CAR_WIDTH = 2.0
MAX_SPEED = 40.0
MIN_SPEED = -40.0
LANE_WIDTH = 4.0
N_LANES = 2


def _default_prior() -> Prior:
    return MixturePrior(HIGHWAY_MODES, jitter=0.1)


def _car_step(
    px: np.ndarray,
    py: np.ndarray,
    v: np.ndarray,
    h: np.ndarray,
    acc: np.ndarray | float,
    steer: np.ndarray | float,
    dt: float,
    length: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One ``Vehicle.step`` on separate component arrays (the fast path for ``dynamics``)."""
    if np.any(np.abs(v) > MAX_SPEED):
        acc = np.where(
            v > MAX_SPEED,
            np.minimum(acc, MAX_SPEED - v),
            np.where(v < MIN_SPEED, np.maximum(acc, MIN_SPEED - v), acc),
        )
    beta = np.arctan(0.5 * np.tan(steer))
    hb = h + beta
    return (
        px + v * np.cos(hb) * dt,
        py + v * np.sin(hb) * dt,
        v + acc * dt,
        h + v * np.sin(beta) / (length / 2) * dt,
    )


def bicycle_step(s: np.ndarray, u: np.ndarray, dt: float, length: float = CAR_LENGTH) -> np.ndarray:
    """highway-env's ``Vehicle.step`` (kinematic bicycle, forward Euler), batched.

    s (..., 4) = (x, y, v, h), u (..., 2) = (acceleration, steering) -> (..., 4). Same operation
    order as highway-env, including its speed clip (acceleration limited once |v| > 40 m/s).
    Collision impacts are not modelled: the env ends the episode on a collision.
    """
    s, u = np.asarray(s, dtype=np.float64), np.asarray(u, dtype=np.float64)
    parts = _car_step(s[..., 0], s[..., 1], s[..., 2], s[..., 3], u[..., 0], u[..., 1], dt, length)
    return np.stack(np.broadcast_arrays(*parts), axis=-1)


def _slip_angles(steer: np.ndarray) -> np.ndarray:
    """β = arctan(½ tan δ) of an array of steering angles, in one new buffer (½ t and t ½ are
    one product: the numbers of ``_car_step``'s spelling)."""
    beta = np.tan(steer)
    beta *= 0.5
    np.arctan(beta, out=beta)
    return beta


@functools.cache
def _phi_kernel() -> Callable[[np.ndarray, np.ndarray], tuple[float, float, float]]:
    """``m6_kernels.highway_phi``, imported once (φ of one state: the env's every step)."""
    from strol_gym.tasks.m6_kernels import highway_phi

    return highway_phi


@functools.cache
def _drawn_kernel() -> Callable[..., int]:
    """``m6_kernels.highway_m6_drawn``, imported once (it loads numba; every correction asks)."""
    from strol_gym.tasks.m6_kernels import highway_m6_drawn

    return highway_m6_drawn


_M6_METHODS = ("g", "g_planes", "_phi", "_step_car", "dynamics")
"""What the Highway's compiled search (``highway_m6_screen``, ``highway_m6_kept``) computes
over again: a subclass overriding one of them takes the plain path."""


@dataclasses.dataclass(frozen=True, eq=False)
class HighwayTask(Task):
    """Two cars on a two-lane highway; the robot learns the human driver's weights θ*.

    Geometry and scales are fields so a variant can be built with ``dataclasses.replace``;
    ``describe()`` records them, so a ĝ trained for one variant is not loaded for another.
    """

    task_id: ClassVar[str] = "StROL-Highway-v0"
    version: ClassVar[int] = 0
    feature_names: ClassVar[tuple[str, ...]] = ("gap", "speed", "lane_change")
    state_dim: ClassVar[int] = 8
    action_dim: ClassVar[int] = 2

    prior: Prior = dataclasses.field(default_factory=_default_prior)
    alpha: float = 1.0
    dt: float = 0.5  # s per policy step (highway-env simulation = policy frequency = 2 Hz)
    max_acceleration: float = 5.0  # m/s², highway-env's ContinuousAction default range
    max_steering: float = 0.02  # rad: a lane change takes about 3 s at 25 m/s
    headway: float = 2.0  # s, the look-ahead T of the gap and lane_change features
    min_gap: float = 10.0  # m, d_min
    gap_scale: float = 20.0  # m
    lane_weight: float = 2.0  # κ: a lateral metre counts as κ metres of following distance
    close_penalty: float = 4.0  # k: slope of the gap feature below d_min, relative to above
    speed_ref: float = 25.0  # m/s
    speed_scale: float = 5.0  # m/s
    heading_scale: float = 0.1  # rad (network input only)
    start_gap: tuple[float, float] = (15.0, 40.0)  # m, centre to centre, human behind
    start_speed: tuple[float, float] = (20.0, 30.0)  # m/s, both cars
    start_x: tuple[float, float] = (50.0, 100.0)  # m, the human car's x (meaningless offset)

    def __post_init__(self) -> None:
        if not isinstance(self.prior, Prior) or self.prior.dim != 3:
            raise ValueError(f"prior must be a Prior over 3 weights, got {self.prior!r}")
        for name in ("alpha", "dt", "max_acceleration", "max_steering", "headway"):
            positive_field(name, getattr(self, name))
        for name in ("gap_scale", "speed_scale", "heading_scale", "lane_weight", "close_penalty"):
            positive_field(name, getattr(self, name))
        for name in ("min_gap", "speed_ref"):
            v = getattr(self, name)
            if not (isinstance(v, int | float | np.number) and np.isfinite(v)):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
        for name in ("start_gap", "start_speed", "start_x"):
            lo, hi = vector_arg(name, getattr(self, name), 2)
            if not lo <= hi:
                raise ValueError(f"{name} must be (low, high) with low <= high, got {(lo, hi)}")
        if self.start_gap[0] <= CAR_LENGTH:
            raise ValueError(f"start_gap must start above the car length {CAR_LENGTH} m")

    # ----------------------------------------------------------------- Task interface
    @property
    def action_bound(self) -> np.ndarray:
        return np.array([self.max_acceleration, self.max_steering])

    @property
    def prior_modes(self) -> np.ndarray:
        return HIGHWAY_MODES

    @property
    def feature_scale(self) -> np.ndarray:
        # Each feature is already divided by its typical range (20 m, 5 m/s, one lane).
        return np.ones(3)

    @property
    def lane_centers(self) -> np.ndarray:
        """y of each lane's centre, left lane first (highway-env's straight road)."""
        return np.arange(N_LANES) * LANE_WIDTH

    def features(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if x.shape == (8,):
            if use_fast() and self._unchanged(HighwayTask, ("_phi",)):
                # compiled: the operations of ``_phi`` (its sine and cosine the C library's,
                # as numpy's: what ``highway_m6_kept`` relies on too)
                return np.array(_phi_kernel()(x, self._kernel_params))
            # One state (the env's every step) as numpy scalars: scalar arithmetic is the same
            # IEEE operations as on 0-d arrays, and the ufuncs the same loops, at less cost.
            return self._phi(*x)
        return self._phi(*(x[..., i] for i in range(8)))

    def _phi(self, *c: np.ndarray) -> np.ndarray:
        """φ from the eight state components as separate (broadcastable) arrays."""
        xr, yr, vr, hr, xh, yh, vh, hh = c
        t = self.headway
        vh_sin = vh * np.sin(hh)
        # T seconds ahead: how far the human is behind the robot (signed) and beside it
        behind = (xr + t * vr * np.cos(hr)) - (xh + t * vh * np.cos(hh))
        beside = (yr + t * vr * np.sin(hr)) - (yh + t * vh_sin)
        short = self.min_gap - behind
        slot = np.maximum(-short, self.close_penalty * short) + self.lane_weight * np.abs(beside)
        lane = (yh + t * vh_sin - self.lane_centers[0]) / LANE_WIDTH
        out = np.empty((*np.broadcast_shapes(slot.shape, vh.shape, lane.shape), 3))
        out[..., 0] = slot
        out[..., 0] /= -self.gap_scale
        out[..., 1] = (vh - self.speed_ref) / self.speed_scale
        out[..., 2] = 1.0 - np.abs(lane - 1.0)
        return out

    def _step_car(self, x: np.ndarray, i: int, u: np.ndarray | None) -> tuple[np.ndarray, ...]:
        """One car's (x, y, v, h) after a step; car i = 0 (robot) or 4 (human); u None = 0."""
        acc, steer = (0.0, 0.0) if u is None else (u[..., 0], u[..., 1])
        return _car_step(
            x[..., i], x[..., i + 1], x[..., i + 2], x[..., i + 3], acc, steer, self.dt, CAR_LENGTH
        )

    def dynamics(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        u_h = np.asarray(u_h, dtype=np.float64)
        u_r = np.asarray(u_r, dtype=np.float64)
        out = np.empty((*np.broadcast_shapes(x.shape[:-1], u_h.shape[:-1], u_r.shape[:-1]), 8))
        # Each car on its own broadcast shape: the robot's part is not repeated per candidate u_H.
        for k, p in enumerate((*self._step_car(x, 0, u_r), *self._step_car(x, 4, u_h))):
            out[..., k] = p
        return out

    def g(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """φ(f(x, u_H, u_R)) − φ(f(x, 0, u_R)), as in ``Task.g``; same values, computed per car
        so eq. M6's candidate search does not rebuild the robot car's state per candidate."""
        x = np.asarray(x, dtype=np.float64)
        u_h = np.asarray(u_h, dtype=np.float64)
        u_r = np.asarray(u_r, dtype=np.float64)
        lead = np.broadcast_shapes(x.shape[:-1], u_h.shape[:-1], u_r.shape[:-1])
        robot = self._step_car(x, 0, u_r)
        out = self._phi(*robot, *self._step_car(x, 4, u_h)) - self._phi(
            *robot, *self._step_car(x, 4, None)
        )
        if out.shape != (*lead, 3):
            out = np.broadcast_to(out, (*lead, 3)).copy()
        return out

    def m6_choice(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_hat: np.ndarray,
        theta_star: np.ndarray,
        candidates: np.ndarray,
    ) -> np.ndarray | None:
        """Eq. M6 by ``strol_gym.tasks.m6_kernels``: a screen drops the candidates that provably
        cannot be chosen (``highway_m6_screen``; one left is the choice), an exact search picks
        among the rest (``highway_m6_kept``, the numbers of ``g``). numpy computes the
        steering angles β = arctan(½ tan δ) it needs in one call: its tangent and arctangent
        are its own SIMD ones, not the C library's that a kernel would call."""
        if not self._unchanged(HighwayTask, _M6_METHODS):
            return None
        from strol_gym.tasks.m6_kernels import highway_m6_kept, highway_m6_screen

        c, f64 = np.ascontiguousarray, np.float64
        x, u_r = c(x, dtype=f64), c(u_r, dtype=f64)
        theta_hat, theta_star = c(theta_hat, dtype=f64), c(theta_star, dtype=f64)
        candidates = np.asarray(candidates, dtype=f64)
        b, k = candidates.shape[:2]
        keep = np.empty((b, k), dtype=np.bool_)
        steer = np.empty(b * (k + 1))
        best = np.empty(b, dtype=np.int64)
        prm = self._kernel_params
        n = highway_m6_screen(x, u_r, theta_hat, theta_star, candidates, prm, keep, steer, best)
        if n:  # people the screen left open
            beta = _slip_angles(steer[:n])
            highway_m6_kept(x, u_r, theta_hat, theta_star, candidates, keep, beta, prm, best)
        return best

    def m6_drawn(self) -> Callable[..., None] | None:
        """``_m6_drawn`` while ``m6_choice`` runs its kernels and the candidates and the noise's
        scale are ``Task``'s."""
        return self._drawn_while(HighwayTask, _M6_METHODS, self._m6_drawn)

    def _m6_drawn(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_hat: np.ndarray,
        theta_star: np.ndarray,
        units: np.ndarray,
        noise: np.ndarray,
        sigma: float,
        bias: float,
        out: np.ndarray,
    ) -> None:
        """``Task.m6_drawn`` by ``m6_kernels.highway_m6_drawn`` for the people its screen settles
        (nearly all); the others' by ``m6_drawn_left``."""
        prm = self.m6_drawn_params(sigma, bias)
        b, k, a = units.shape
        cand, keep = np.empty((b, k + 1, a)), np.empty((b, k + 1), dtype=np.bool_)
        steer, best = np.empty(b * (k + 2)), np.empty(b, dtype=np.int64)
        rows = (x, u_r, theta_hat, theta_star)
        n = _drawn_kernel()(*rows, units, noise, prm, cand, keep, steer, best, out)
        if n:
            self.m6_drawn_left(*rows, noise, prm, cand, keep, steer[:n], best, out)

    def m6_drawn_params(self, sigma: float, bias: float) -> np.ndarray:
        """What ``highway_m6_drawn`` reads of the Task and the noise, in its order: the search's
        numbers (``_kernel_params``), σ, ε, the candidates' bound and a_max (once per σ, ε)."""
        memo = self.__dict__.setdefault("_m6_drawn_memo", {})  # as ``_unchanged``'s
        prm = memo.get((sigma, bias))
        if prm is None:
            prm = memo[sigma, bias] = np.concatenate(
                [self._kernel_params, [sigma, bias], self._axis_scale, self.a_max]
            ).astype(np.float64)
        return prm

    def m6_drawn_left(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_hat: np.ndarray,
        theta_star: np.ndarray,
        noise: np.ndarray,
        prm: np.ndarray,
        cand: np.ndarray,
        keep: np.ndarray,
        steer: np.ndarray,
        best: np.ndarray,
        out: np.ndarray,
    ) -> None:
        """The people ``highway_m6_drawn`` left to the exact search (``best`` −1): what
        ``m6_choice`` does after its screen (numpy's steering angles of the packed ``steer``,
        then ``highway_m6_kept`` among the kept candidates), then their noise by ``perturb``.
        ``prm`` as ``m6_drawn_params`` gives it."""
        from strol_gym.humans.choices import perturb
        from strol_gym.humans.interface import Replayed
        from strol_gym.tasks.m6_kernels import highway_m6_kept

        left = np.flatnonzero(best < 0)
        n_prm = len(prm) - 6
        sigma, bias = float(prm[n_prm]), float(prm[n_prm + 1])
        beta = _slip_angles(steer)
        highway_m6_kept(x, u_r, theta_hat, theta_star, cand, keep, beta, prm[:n_prm], best)
        out[left] = perturb(self, cand[left, best[left]], sigma, bias, Replayed(noise[left]))

    @functools.cached_property
    def _kernel_params(self) -> np.ndarray:
        """The numbers the compiled search reads, in its order."""
        return np.array(
            [
                self.headway,
                self.min_gap,
                self.close_penalty,
                self.lane_weight,
                float(self.lane_centers[0]),
                LANE_WIDTH,
                self.gap_scale,
                self.speed_ref,
                self.speed_scale,
                self.alpha,
                self.dt,
                CAR_LENGTH / 2,
                MAX_SPEED,
                MIN_SPEED,
            ],
            dtype=np.float64,
        )

    def sample_episode_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Where an episode of the env starts: both cars in the left lane, the human behind.

        Gap ``start_gap`` (15–40 m), speeds ``start_speed`` (20–30 m/s), small lateral offsets
        (robot ±0.5 m, human ±1 m, inside the 4 m lane) and headings (±0.02 / ±0.05 rad).
        """
        return self._episode_start(rng.uniform(size=(n, 8)))

    def sample_episode_starts(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """``sample_episode_start(rng, 1)`` for each generator, stacked (a vector env's resets):
        the draws per generator, the arithmetic once on the batch (the same numbers)."""
        if len(rngs) == 1:  # a single env's reset
            return self.sample_episode_start(rngs[0], 1)
        return self._episode_start(np.concatenate([rng.uniform(size=(1, 8)) for rng in rngs]))

    def _episode_start(self, u: np.ndarray) -> np.ndarray:
        return self._lerp(
            u,
            self.start_gap,
            (-0.5, 0.5),
            (-1.0, 1.0),
            (-0.02, 0.02),
            (-0.05, 0.05),
            self.start_speed,
            self.start_speed,
        )

    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """States an interaction visits, for training ĝ (``learners.training``) and Task-level
        simulation: broader than an episode's start (``sample_episode_start``).

        The corrections move the human car far from where it started within 10 steps (the eq.
        M6 teacher's car drifts by up to ±10 m sideways, 20–35 m/s, up to ±0.2 rad; the robot
        policy moves the robot to the right lane), and a ĝ trained on start states alone
        extrapolates badly there: its error grows again after a few corrections. So: human
        −10 to 60 m behind (ahead after passing), robot y ∈ [−1, 5] m, human y ∈ [−6, 10] m,
        speeds 15–35 m/s, headings ±0.1 (robot) / ±0.2 rad (human).
        """
        return self._lerp(
            rng.uniform(size=(n, 8)),
            (-10.0, 60.0),
            (-1.0, 5.0),
            (-6.0, 10.0),
            (-0.1, 0.1),
            (-0.2, 0.2),
            (15.0, 35.0),
            (15.0, 35.0),
        )

    def _lerp(
        self,
        u: np.ndarray,
        behind: tuple[float, float],
        y_r: tuple[float, float],
        y_h: tuple[float, float],
        h_r: tuple[float, float],
        h_h: tuple[float, float],
        v_r: tuple[float, float],
        v_h: tuple[float, float],
    ) -> np.ndarray:
        """States from uniform draws ``u`` (n, 8), each column mapped into its range."""
        n = len(u)
        ranges = (self.start_x, behind, y_r, y_h, h_r, h_h, v_r, v_h)
        if n == 1 and all(type(v) is float for r in ranges for v in r):
            # One env's reset in plain floats (the bounds Python floats, so float64 as in
            # numpy): the same operations, without numpy's per-call cost on single numbers.
            c = u[0].tolist()
            x_h = self.start_x[0] + (self.start_x[1] - self.start_x[0]) * c[0]
            row = [x_h + (behind[0] + (behind[1] - behind[0]) * c[1])]
            for col, (lo, hi) in zip((4, 2, 6), (y_r, v_r, h_r), strict=True):
                row.append(lo + (hi - lo) * c[col])
            row.append(x_h)
            for col, (lo, hi) in zip((5, 3, 7), (y_h, v_h, h_h), strict=True):
                row.append(lo + (hi - lo) * c[col])
            return np.array([row])

        def lerp(col: int, lo: float, hi: float) -> np.ndarray:
            return lo + (hi - lo) * u[:, col]

        x = np.empty((n, 8))
        x[:, 4] = lerp(0, *self.start_x)
        x[:, 0] = x[:, 4] + lerp(1, *behind)
        x[:, 2] = lerp(2, *v_r)
        x[:, 6] = lerp(3, *v_h)
        x[:, 1] = lerp(4, *y_r)
        x[:, 5] = lerp(5, *y_h)
        x[:, 3] = lerp(6, *h_r)
        x[:, 7] = lerp(7, *h_h)
        return x

    def network_input(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        """Scale-free relative quantities (absolute x on the road means nothing), width 10:

        (x_R − x_H)/20 m, (y_R − y_H)/4 m, y_R/4 m, y_H/4 m, (v_R − 25)/5, (v_H − 25)/5,
        h_R/0.1 rad, h_H/0.1 rad, u_H/a_max (2).
        """
        x = np.asarray(x, dtype=np.float64)
        u_h = np.asarray(u_h, dtype=np.float64)
        lead = np.broadcast_shapes(x.shape[:-1], u_h.shape[:-1])
        x = np.broadcast_to(x, (*lead, 8))
        out = np.empty((*lead, 10))
        out[..., 0] = (x[..., 0] - x[..., 4]) / self.gap_scale
        out[..., 1] = (x[..., 1] - x[..., 5]) / LANE_WIDTH
        out[..., 2] = x[..., 1] / LANE_WIDTH
        out[..., 3] = x[..., 5] / LANE_WIDTH
        out[..., 4] = (x[..., 2] - self.speed_ref) / self.speed_scale
        out[..., 5] = (x[..., 6] - self.speed_ref) / self.speed_scale
        out[..., 6] = x[..., 3] / self.heading_scale
        out[..., 7] = x[..., 7] / self.heading_scale
        out[..., 8:] = np.broadcast_to(u_h, (*lead, 2)) / self.action_bound
        return out

    # ----------------------------------------------------------------- default robot policy
    def robot_policy(self, x: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
        """The benchmark's robot car: keep right at its speed, but yield to a human who passes.

        (B, 8), (B, 3) -> (B, 2) in task units. The robot prefers the right lane (the keep-right
        rule: it leaves the left lane to overtaking traffic) at its current speed; it holds on
        to the left lane when it expects the human to pass there on the right. It scores four
        manoeuvres, (stay in the current lane | go to the right lane) x (hold speed | slow by
        5 m/s), each flown by a lane- and speed-tracking controller for ``POLICY_HORIZON`` steps
        while the human is predicted with θ̂ by the ``driver`` model (receding horizon: each
        predicted step is ``driver_correction`` over a 5 x 5 action grid, reacting to
        the robot's manoeuvre). Cost per step: distance from the right lane's centre (lanes)
        + 0.5 x speed change (m/s) + 1000 if the predicted cars are closer than two car lengths
        longitudinally and 3 m laterally. The first action of the cheapest manoeuvre is returned.
        So θ̂ matters: a predicted tailgater follows it into the right lane, a predicted
        right-hand passer makes it keep the left lane.
        """
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        theta_hat = np.atleast_2d(np.asarray(theta_hat, dtype=np.float64))
        b = len(x)
        grid = np.stack(np.meshgrid(np.linspace(-1, 1, 5), np.linspace(-1, 1, 5)), -1)
        grid = grid.reshape(-1, 2) * self.action_bound
        lanes = self.lane_centers
        here = lanes[np.argmin(np.abs(x[:, 1:2] - lanes), axis=1)]
        y_goal = np.stack([here, here, np.full(b, lanes[-1]), np.full(b, lanes[-1])], axis=1)
        v_goal = x[:, 2:3] + np.array([0.0, -5.0, 0.0, -5.0])
        m = y_goal.shape[1]
        xs = np.repeat(x[:, None, :], m, axis=1).reshape(b * m, 8)
        y_goal, v_goal = y_goal.reshape(-1), v_goal.reshape(-1)
        th = np.repeat(theta_hat, m, axis=0)
        cand = np.broadcast_to(grid, (b * m, *grid.shape))
        cost = np.zeros(b * m)
        first: np.ndarray | None = None
        for _ in range(POLICY_HORIZON):
            u_r = self._track(xs[:, :4], y_goal, v_goal)
            if first is None:
                first = u_r
            u_h = driver_correction(self, xs, u_r, th, cand, DRIVER_HORIZON)
            nxt = self.dynamics(xs, u_h, u_r)
            cost += np.abs(nxt[:, 1] - lanes[-1]) / LANE_WIDTH
            cost += 0.5 * np.abs(nxt[:, 2] - xs[:, 2])
            close = (np.abs(nxt[:, 0] - nxt[:, 4]) < 2 * CAR_LENGTH) & (
                np.abs(nxt[:, 1] - nxt[:, 5]) < 3.0
            )
            cost += 1000.0 * close
            xs = nxt
        best = np.argmin(cost.reshape(b, m), axis=1)
        assert first is not None  # POLICY_HORIZON >= 1
        return first.reshape(b, m, 2)[np.arange(b), best]

    def _track(self, s: np.ndarray, y_goal: np.ndarray, v_goal: np.ndarray) -> np.ndarray:
        """Lane- and speed-tracking controller (..., 4) -> (..., 2), within the action bound.

        Desired heading steers the lateral error out at 0.5 /s (capped at 0.1 rad); the steering
        that reaches it in one step inverts the bicycle model's heading rate.
        """
        v = np.maximum(s[..., 2], 1.0)
        h_goal = np.clip(np.arctan2(0.5 * (y_goal - s[..., 1]), v), -0.1, 0.1)
        sin_beta = (h_goal - s[..., 3]) * (CAR_LENGTH / 2) / (v * self.dt)
        beta = np.arcsin(np.clip(sin_beta, -0.5, 0.5))
        steer = np.arctan(2.0 * np.tan(beta))
        acc = (v_goal - s[..., 2]) / self.dt
        u = np.stack([acc, steer], axis=-1)
        return np.clip(u, -self.action_bound, self.action_bound)


POLICY_HORIZON = 8
"""Steps (4 s) over which the default robot policy predicts the human and scores manoeuvres."""
DRIVER_HORIZON = 4
"""Steps (2 s) of the driver model the robot policy predicts the human with (as ``DriverHuman``)."""
