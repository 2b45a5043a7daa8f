"""A zoo of correction models: people who are not the eq. M6 teacher in one way each.

Robustness claims depend on the human model, so the benchmark can swap the teacher for one who
is noisier where it matters, short-sighted, silent at times, heavy- or light-handed, early or
late, or sometimes wrong about what it wants. Each model below is a registered human
(``strol_gym.humans.HUMANS``); every one but ``myopic`` is the eq. M6 teacher
(:class:`~strol_gym.humans.builtin.NominalModel`, the envs' default human) changed in exactly one
respect, so a difference in a learner's score is that respect's doing.

All of them keep the interface's promises: their extra randomness is drawn in
``draw_extra`` from the caller's generator, the same number of draws whatever θ̂ (paired runs);
a person who does not correct answers u_H = 0 exactly (no noise), yet its candidates and noise
are still drawn, so the next correction sees the same draws as it would have.

What a zero correction does downstream (``docs/humans.md``): the env still counts the step as a
correction (``info["is_correction"]`` is True, ``info["correction"]`` is 0), the wrapper hands
it to the learner, g(x, 0, u_R) = φ(x_R) − φ(x_R) = 0, so Gradient, One, MOF, StROL and e2e
(‖ĝ‖ ≤ ‖g‖ = 0) leave θ̂ unchanged; the Bayesian learner reads "no correction" as evidence
(every candidate would have lost reward) and moves its posterior.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from strol_gym.humans.builtin import DriverModel, NominalModel
from strol_gym.humans.checks import check_fraction
from strol_gym.humans.choices import perturb
from strol_gym.humans.interface import DEFAULT_CANDIDATES, Replayed, SimulatedHuman
from strol_gym.tasks.base import Task

MAX_SCALE = 10.0
"""The largest magnitude scale of the over-correcting person: beyond ten times the teacher's
correction it is no longer a correction of this robot's motion."""


def check_probability(name: str, value: Any) -> float:
    """A probability in [0, 1] (a number or a numeric string), else ValueError naming it."""
    rng = "a probability in [0, 1]"
    if isinstance(value, bool | np.bool_):
        raise ValueError(f"{name} must be {rng}, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {rng}, got {value!r}") from None
    if not (math.isfinite(v) and 0.0 <= v <= 1.0):
        raise ValueError(f"{name} must be {rng}, got {value!r}")
    return v


def check_index(name: str, value: Any, low: int) -> int:
    """A correction index, an integer >= ``low``, else ValueError naming it."""
    ok = isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)
    if not ok or int(value) < low:
        raise ValueError(f"{name} must be an integer >= {low} (a correction index), got {value!r}")
    return int(value)


def _silence(u: np.ndarray, quiet: np.ndarray) -> np.ndarray:
    """u with the rows where ``quiet`` (n,) is True set to exactly 0: no correction."""
    quiet = np.broadcast_to(np.asarray(quiet, dtype=bool), (len(u),))
    return np.where(quiet[:, None], 0.0, u)


class FeatureNoiseModel(NominalModel):
    """Feature-dependent noise: the eq. M6 teacher whose hand is noisier when it matters.

    Model: u* is the teacher's choice; u_H = u* + δ with δ ~ N(ε a_max, (σ_x a_max)²) per
    component, where σ_x = σ + κ·r grows with

    - ``noise_with="g"`` (default): r = ‖g(x, u*, u_R) / s‖ / max_c ‖g(x, c, u_R) / s‖ over the
      person's candidates c (s = ``task.feature_scale``), in [0, 1]: the larger the feature
      change the correction carries, relative to the largest available, the noisier it is;
    - ``noise_with=<feature name>``: r = |φ_i(x)| / s_i, the size of that feature where the
      person corrects (the Robot's ``cup_distance``: the farther from the cup, the noisier).

    The noise is zero-mean beyond ε, but its size tracks the very quantity the learners read,
    so the corrections that carry most information carry most noise. Parameters: σ, ε
    (fractions of a_max), ``kappa`` = κ (≥ 0, in units of a_max, default 0.5), ``noise_with``,
    ``n_candidates``.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        kappa: float = 0.5,
        noise_with: str = "g",
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.kappa = check_fraction("kappa", kappa)
        names = ("g", *task.feature_names)
        if not isinstance(noise_with, str) or noise_with not in names:
            raise ValueError(f"noise_with must be one of {list(names)}, got {noise_with!r}")
        self.noise_with = noise_with

    def noise_scale(
        self, x: np.ndarray, u_r: np.ndarray, u: np.ndarray, candidates: np.ndarray
    ) -> np.ndarray:
        """σ_x (n,) for people at x who chose u among ``candidates`` (see the class docstring)."""
        scale = np.asarray(self.task.feature_scale, dtype=np.float64)
        if self.noise_with == "g":
            g_all = self.task.g(x[:, None, :], candidates, u_r[:, None, :]) / scale
            top = np.linalg.norm(g_all, axis=-1).max(axis=1)
            own = np.linalg.norm(self.task.g(x, u, u_r) / scale, axis=-1)
            r = np.divide(own, top, out=np.zeros_like(own), where=top > 0)
        else:
            i = self.task.feature_names.index(self.noise_with)
            r = np.abs(self.task.features(x)[..., i]) / scale[i]
        return self.sigma + self.kappa * r

    def corrections(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        if theta_hat is None:
            raise ValueError(f"{type(self).__name__} teaches relative to θ̂: pass theta_hat")
        pref = self.preference(theta_star, k)
        u = self.choose(x, u_r, pref, draws, theta_hat, k)
        sigma = self.noise_scale(x, u_r, u, draws.candidates)[:, None]
        return perturb(self.task, u, sigma, self.bias, Replayed(draws.noise))


class MyopicModel(DriverModel):
    """Myopic: corrects for the next step only, u* = argmax_c θ*·φ(f(x, c, u_R)) over its
    candidates, then δ. It neither teaches (no θ̂) nor looks past the next state.

    Per Task, f is the Task's own one-step transition, so "the next step" is:

    - Robot: the next waypoint x' = clip(x + u_R + u_H) (the env tracks it with IK); the person
      moves it as far toward what θ* likes (the plate, away from the cup, ...) as one step of
      ±a_max per axis allows;
    - Highway: the next 1-step state of both cars (highway-env's bicycle model); the features'
      2 s look-ahead makes one step's acceleration and steering count;
    - Study (v0, and v1's ``participant="oracle"``): the cup's pose after the push (u_R = 0 as
      the simulated user asks), the best admissible pose change under θ*.

    It is the short-horizon driver (``driver``) with a horizon of 1 and the teacher's candidate
    count, and the greedy argmax θ*·g human, since θ*·g = θ*·φ(x_H) − θ*·φ(x_R).
    Parameters: σ, ε, ``n_candidates`` (default 512).
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, horizon=1, n_candidates=n_candidates)


class SkippingModel(NominalModel):
    """Skipping: with probability ``p`` a correction is not given, u_H = 0 exactly (no noise);
    otherwise the eq. M6 teacher's u* + δ. Each correction skips independently (a uniform draw
    per correction, taken whatever the outcome). Parameters: σ, ε, ``p`` ∈ [0, 1] (default
    0.3), ``n_candidates``.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        p: float = 0.3,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.p = check_probability("p", p)

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        return {"skip": rng.random(n)}

    def corrections(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        u = super().corrections(x, u_r, theta_star, draws, theta_hat, k)
        return _silence(u, draws.extra["skip"] < self.p)


class _ScaledModel(NominalModel):
    """The teacher's noise-free u* times ``scale``, then δ (the shared body of over/under)."""

    low: float = 0.0
    high: float = MAX_SCALE
    default_scale: float = 1.0

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        scale: float | None = None,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        value = self.default_scale if scale is None else scale
        low = "(0" if self.low == 0 else f"[{self.low:g}"
        rng = f"a number in {low}, {self.high:g}]"
        try:
            s = math.nan if isinstance(value, bool | np.bool_) else float(value)
        except (TypeError, ValueError):
            s = math.nan
        if not (
            math.isfinite(s) and s <= self.high and (s > 0 if self.low == 0 else s >= self.low)
        ):
            raise ValueError(f"scale must be {rng}, got {value!r}")
        self.scale = s

    def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        return self.scale * super().choose(x, u_r, theta_star, draws, theta_hat, k)


class OverCorrectingModel(_ScaledModel):
    """Over-correcting: pushes ``scale`` times as far as the eq. M6 teacher would,
    u_H = scale·u* + δ (the noise is the hand's, not scaled). With scale 2 a teacher's
    correction that would bring θ̂ to θ* carries it as far past. Parameters: σ, ε, ``scale``
    ∈ [1, 10] (default 2), ``n_candidates``. The result may exceed a_max per axis.
    """

    low = 1.0
    default_scale = 2.0


class UnderCorrectingModel(_ScaledModel):
    """Under-correcting: pushes only ``scale`` of the way the eq. M6 teacher would,
    u_H = scale·u* + δ. Parameters: σ, ε, ``scale`` ∈ (0, 1] (default 0.5), ``n_candidates``.
    """

    low = 0.0
    high = 1.0
    default_scale = 0.5


class _WindowModel(NominalModel):
    """The teacher during corrections k ∈ [start, stop), silent (u_H = 0) outside them."""

    start = 0
    stop: float = math.inf

    def corrections(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        u = super().corrections(x, u_r, theta_star, draws, theta_hat, k)
        k = np.asarray(k)
        return _silence(u, (k < self.start) | (k >= self.stop))


class EarlyModel(_WindowModel):
    """Early: corrects only for its first ``until`` corrections (correction index k < until),
    then gives none (u_H = 0): the person who sets the robot straight at the start and then
    lets it be. Parameters: σ, ε, ``until`` (integer ≥ 1, default 2), ``n_candidates``.

    k is the correction's index in the episode (0 for the first). ĝ's training data are single
    corrections asked with k = 0, so there it corrects like the teacher.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        until: int = 2,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.stop = check_index("until", until, 1)


class LateModel(_WindowModel):
    """Late: gives no correction (u_H = 0) before correction index ``start``, then corrects as
    the eq. M6 teacher: the person who watches first and steps in later. Parameters: σ, ε,
    ``start`` (integer ≥ 0, default 3), ``n_candidates``.

    ĝ's training data are single corrections asked with k = 0: with start ≥ 1 every sample is
    a zero correction, and training leaves ĝ where it started (docs/humans.md).
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        start: int = 3,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.start = check_index("start", start, 0)


class MistakenModel(NominalModel):
    """Mistaken: with probability ``rate`` a correction teaches toward a wrong θ instead of θ*.

    Per correction it draws a uniform number and a θ_wrong from the Task's prior (the prior
    θ* itself comes from: bimodal or uniform); if the number is below ``rate``, u* is the eq. M6
    correction toward θ_wrong, else toward θ*; then δ. Both draws are taken whatever the
    outcome. On the bimodal prior θ_wrong lies in θ*'s own mode about half the time, so a
    mistake is then a small one. Parameters: σ, ε, ``rate`` ∈ [0, 1] (default 0.2),
    ``n_candidates``.
    """

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        rate: float = 0.2,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        super().__init__(task, sigma, bias, n_candidates)
        self.rate = check_probability("rate", rate)

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        mistake = rng.random(n)
        return {"mistake": mistake, "wrong_theta": self.task.prior.sample(rng, n)}

    def choose(self, x, u_r, theta_star, draws, theta_hat=None, k=0):
        wrong = draws.extra["mistake"] < self.rate
        target = np.where(wrong[:, None], draws.extra["wrong_theta"], theta_star)
        return super().choose(x, u_r, target, draws, theta_hat, k)


ZOO: dict[str, type[NominalModel] | type[DriverModel]] = {
    "feature-noise": FeatureNoiseModel,
    "myopic": MyopicModel,
    "skipping": SkippingModel,
    "over": OverCorrectingModel,
    "under": UnderCorrectingModel,
    "early": EarlyModel,
    "late": LateModel,
    "mistaken": MistakenModel,
}
"""The zoo's names (registered in ``strol_gym.humans.registry.HUMAN_MODELS``)."""

FeatureNoiseHuman = SimulatedHuman.of(FeatureNoiseModel, "FeatureNoiseHuman")
MyopicHuman = SimulatedHuman.of(MyopicModel, "MyopicHuman")
SkippingHuman = SimulatedHuman.of(SkippingModel, "SkippingHuman")
OverCorrectingHuman = SimulatedHuman.of(OverCorrectingModel, "OverCorrectingHuman")
UnderCorrectingHuman = SimulatedHuman.of(UnderCorrectingModel, "UnderCorrectingHuman")
EarlyHuman = SimulatedHuman.of(EarlyModel, "EarlyHuman")
LateHuman = SimulatedHuman.of(LateModel, "LateHuman")
MistakenHuman = SimulatedHuman.of(MistakenModel, "MistakenHuman")

__all__ = [
    "ZOO",
    "EarlyHuman",
    "EarlyModel",
    "FeatureNoiseHuman",
    "FeatureNoiseModel",
    "LateHuman",
    "LateModel",
    "MistakenHuman",
    "MistakenModel",
    "MyopicHuman",
    "MyopicModel",
    "OverCorrectingHuman",
    "OverCorrectingModel",
    "SkippingHuman",
    "SkippingModel",
    "UnderCorrectingHuman",
    "UnderCorrectingModel",
    "check_index",
    "check_probability",
]
