"""Priors P(θ) over reward weights: what the simulated humans draw θ* from."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from strol_gym import checks
from strol_gym.compiled import use_fast
from strol_gym.registry import Registry


@runtime_checkable
class Prior(Protocol):
    """A distribution over θ ∈ R^d. ``mean`` is the robot's initial estimate θ̂0."""

    @property
    def dim(self) -> int:
        """d, fixed when the prior is built (read-only: priors are frozen dataclasses)."""
        ...

    @property
    def mean(self) -> np.ndarray: ...

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Draw ``n`` weight vectors, shape (n, d)."""
        ...


MAX_THETA = 1e6
"""The largest |component| of a θ a prior or a ``theta_star`` may hold: the paper's θ lie in
[−1, 1] and basin maps reach 10; far larger values (1e308) make rewards θ·φ overflow to inf."""


def check_theta_range(name: str, values: np.ndarray) -> None:
    """ValueError naming ``name`` unless every component is finite and within ±MAX_THETA."""
    if not np.isfinite(values).all() or (np.abs(values) > MAX_THETA).any():
        raise ValueError(
            f"{name} must be finite numbers in [-{MAX_THETA:g}, {MAX_THETA:g}], "
            f"got {np.asarray(values).tolist()!r:.80}"
        )


@dataclass(frozen=True)
class MixturePrior:
    """Equal-weight mixture of modes with isotropic Gaussian jitter (the paper's bimodal prior)."""

    modes: np.ndarray
    jitter: float = 0.1
    name: str = "bimodal"
    dim: int = field(init=False)

    def __post_init__(self) -> None:
        modes = np.atleast_2d(np.asarray(self.modes, dtype=np.float64))
        if modes.ndim != 2 or modes.shape[0] < 1:
            raise ValueError(f"modes must have shape (k, d) with k >= 1, got {modes.shape}")
        check_theta_range("modes", modes)
        if not (np.isfinite(self.jitter) and self.jitter >= 0):
            raise ValueError(f"jitter must be a finite number >= 0, got {self.jitter}")
        object.__setattr__(self, "modes", modes)
        object.__setattr__(self, "dim", modes.shape[1])

    @property
    def mean(self) -> np.ndarray:
        return self.modes.mean(axis=0)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if n == 1:  # one env's reset: ``sample_each``'s draws, without size=1's per-call cost
            return self.sample_each([rng])
        idx = rng.integers(0, len(self.modes), size=n)
        return self.modes[idx] + self.jitter * rng.standard_normal((n, self.dim))

    def sample_each(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """``sample(rng, 1)`` from each generator, stacked (len(rngs), d): the draws stay per
        generator (its index, then its jitter; a scalar draw is size=1's), the arithmetic
        runs once on the batch, so the same numbers."""
        k = len(self.modes)
        if len(rngs) == 1:  # one env's reset: the same draws and elementwise operations
            rng = rngs[0]
            i = rng.integers(0, k)
            return (self.modes[i] + self.jitter * rng.standard_normal(self.dim))[None]
        drawn = _compiled_draws(rngs, k, self.dim)
        if drawn is None:
            idx = np.array([rng.integers(0, k) for rng in rngs], dtype=np.int64)
            z = np.array([rng.standard_normal(self.dim) for rng in rngs])
            drawn = idx, z.reshape(len(rngs), self.dim)
        return self.modes[drawn[0]] + self.jitter * drawn[1]


def _compiled_draws(
    rngs: Sequence[np.random.Generator], k: int, dim: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """``integers(0, k)`` then ``standard_normal(dim)`` from each generator in one compiled
    call (``pcg64_fill.mixture``, numpy's numbers): (indices, normals (B, dim)); None where the
    fast kernels are off or it cannot give numpy's numbers (a generator not a ``PCG64``)."""
    if not (use_fast() and 0 < k < 2**32 - 1):
        return None
    from strol_gym.pcg64_fill import addresses, mixture

    states = addresses(rngs, ("mixture",))
    if states is None:
        return None
    idx, z = np.empty(len(rngs), dtype=np.int64), np.empty((len(rngs), dim))
    mixture(states, k, idx, z)
    return idx, z


def sample_each(prior: Prior, rngs: Sequence[np.random.Generator]) -> np.ndarray:
    """One θ from each generator, (len(rngs), d): ``prior.sample(rng, 1)`` per generator, or
    the prior's own ``sample_each`` when it has one (the same numbers, batched)."""
    own = getattr(prior, "sample_each", None)
    if own is not None:
        return own(rngs)
    return np.concatenate([prior.sample(rng, 1) for rng in rngs]).reshape(len(rngs), prior.dim)


@dataclass(frozen=True)
class UniformPrior:
    """Uniform over the box [low, high]^d (the paper's 'uniform prior' condition)."""

    dim: int
    low: float = -1.0
    high: float = 1.0
    name: str = "uniform"

    def __post_init__(self) -> None:
        if self.dim < 1:
            raise ValueError(f"dim must be >= 1, got {self.dim}")
        if not (np.isfinite(self.low) and np.isfinite(self.high) and self.low < self.high):
            raise ValueError(f"need finite low < high, got low={self.low}, high={self.high}")
        check_theta_range("low and high", np.array([self.low, self.high], dtype=np.float64))

    @property
    def mean(self) -> np.ndarray:
        return np.full(self.dim, 0.5 * (self.low + self.high))

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return rng.uniform(self.low, self.high, size=(n, self.dim))


@dataclass(frozen=True)
class FixedPrior:
    """A point mass (or a finite set, drawn uniformly): for tests and hand-picked θ*."""

    thetas: np.ndarray
    name: str = "fixed"
    dim: int = field(init=False)

    def __post_init__(self) -> None:
        try:
            thetas = np.atleast_2d(np.asarray(self.thetas, dtype=np.float64))
        except (TypeError, ValueError):
            raise ValueError(
                f"thetas must be numbers of shape (k, d), got {self.thetas!r}"
            ) from None
        if thetas.ndim != 2 or thetas.shape[0] < 1 or thetas.shape[1] < 1:
            raise ValueError(f"thetas must have shape (k, d) with k, d >= 1, got {thetas.shape}")
        check_theta_range("thetas", thetas)
        object.__setattr__(self, "thetas", thetas)
        object.__setattr__(self, "dim", thetas.shape[1])

    @property
    def mean(self) -> np.ndarray:
        return self.thetas.mean(axis=0)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return self.thetas[rng.integers(0, len(self.thetas), size=n)]


PriorFactory = Callable[[np.ndarray], Prior]
"""A named prior: built from the Task's designer modes (k, d)."""


def _bimodal(task_modes: np.ndarray) -> Prior:
    """The designer's modes, equally likely (the paper's bimodal prior)."""
    return MixturePrior(task_modes)


def _uniform(task_modes: np.ndarray) -> Prior:
    """θ* uniform over [−1, 1]^d (the benchmark's uniform-prior condition)."""
    return UniformPrior(task_modes.shape[1])


PRIOR_FACTORIES: dict[str, PriorFactory | str] = {"bimodal": _bimodal, "uniform": _uniform}
"""The named priors; ``register_prior`` adds to it (through ``PRIORS``)."""
PRIORS = Registry[PriorFactory](
    "prior",
    PRIOR_FACTORIES,
    callable_as="(task_modes) -> Prior",
    hint=" naming a factory (task_modes) -> Prior",
)


def register_prior(name: str, factory: PriorFactory | str) -> None:
    """Make ``factory(task_modes) -> Prior`` available as ``prior=name`` in the envs and as a
    condition's prior in the benchmark (it may be a lazy ``"module:attr"`` string)."""
    PRIORS.register(name, factory)


def make_prior(spec: str | Prior | Sequence[Sequence[float]], task_modes: np.ndarray) -> Prior:
    """Resolve a user's prior argument: a registered name ("bimodal", "uniform", ...) or
    "module:attr" of a factory, a Prior object, or explicit modes."""
    task_modes = np.atleast_2d(task_modes)
    if isinstance(spec, str):
        factory = PRIORS.get(spec)
        try:
            prior = factory(task_modes)
        except Exception as e:  # a 'module:attr' naming something that is not a factory
            raise ValueError(
                f"prior {spec!r}: its factory (task_modes) -> Prior failed "
                f"({type(e).__name__}: {' '.join(str(e).split())[:120]})"
            ) from None
        if not isinstance(prior, Prior):
            raise ValueError(f"prior {spec!r} gave {type(prior).__name__}, not a Prior")
        if prior.dim != task_modes.shape[1]:
            raise ValueError(
                f"prior {spec!r} has dim {prior.dim}, the task needs {task_modes.shape[1]}"
            )
        return prior
    if isinstance(spec, Prior):
        if spec.dim != task_modes.shape[1]:
            raise ValueError(f"prior has dim {spec.dim}, the task needs {task_modes.shape[1]}")
        return spec
    modes = np.atleast_2d(checks.array("prior", spec))
    if modes.ndim != 2 or modes.shape[1] != task_modes.shape[1]:
        raise ValueError(f"prior modes need {task_modes.shape[1]} columns, got shape {modes.shape}")
    return MixturePrior(modes, name="custom")


@dataclass(frozen=True)
class HedgedPrior:
    """The designer's bimodal prior with a hedge: with probability ``broad_weight`` θ comes from
    a broad Gaussian N(mean of the modes, s² I) instead, s = the largest |mode entry| (unless
    ``broad_scale`` is given). It says "probably one of these modes, but maybe neither"; it is
    not the uniform distribution the benchmark's uniform-prior condition draws θ* from."""

    modes: np.ndarray
    jitter: float = 0.1
    broad_weight: float = 0.2
    broad_scale: float | None = None
    name: str = "hedged"
    dim: int = field(init=False)

    def __post_init__(self) -> None:
        bimodal = MixturePrior(self.modes, self.jitter)
        if not (np.isfinite(self.broad_weight) and 0.0 <= self.broad_weight <= 1.0):
            raise ValueError(f"broad_weight must be in [0, 1], got {self.broad_weight!r}")
        scale = self.broad_scale
        scale = float(np.abs(bimodal.modes).max()) if scale is None else float(scale)
        if not (np.isfinite(scale) and scale >= 0):
            raise ValueError(f"broad_scale must be a finite number >= 0, got {self.broad_scale!r}")
        object.__setattr__(self, "modes", bimodal.modes)
        object.__setattr__(self, "broad_scale", scale)
        object.__setattr__(self, "dim", bimodal.dim)

    @property
    def mean(self) -> np.ndarray:
        return self.modes.mean(axis=0)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        assert self.broad_scale is not None  # resolved to a number by __post_init__
        out = MixturePrior(self.modes, self.jitter).sample(rng, n)
        broad = rng.random(n) < self.broad_weight
        out[broad] = self.mean + self.broad_scale * rng.standard_normal(
            (int(broad.sum()), self.dim)
        )
        return out
