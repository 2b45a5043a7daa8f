"""The one human interface: a model of how people correct, asked for a whole batch at once.

A :class:`HumanModel` holds what a population of simulated people shares (the Task, noise σ,
bias ε, the number of candidate actions and the model's own parameters) and answers for a batch
of people, each with their own state, θ* and (for models that teach) the robot's estimate θ̂.
Randomness is split from the choice so that one model serves every caller:

- :meth:`HumanModel.draw` takes everything random for n corrections from one generator, in a
  fixed order per correction (candidates, the model's extra draws, the noise);
- :meth:`HumanModel.choose` picks the noise-free corrections from those draws, batched;
- :meth:`HumanModel.corrections` adds δ = ε a_max + σ a_max z.

Training and the Task-level simulations draw a whole batch from one generator; a vector env
draws each sub-env's corrections from that sub-env's own generator (:meth:`draw_each`), so that
sub-env b sees the bytes a single env would, and still chooses for all of them in one call.

θ̂ goes only to models that declare ``needs_theta_hat`` (the eq. M6 teacher does; a person who
judges what they see does not). The single-sample ``Human.act`` of the envs is the thin adapter
:class:`SimulatedHuman`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from strol_gym.draws import uniform_rows
from strol_gym.humans.checks import check_fraction
from strol_gym.humans.choices import perturb
from strol_gym.limits import check_size
from strol_gym.tasks.base import Task

DEFAULT_CANDIDATES = 512


@runtime_checkable
class Human(Protocol):
    """Anything that can correct the robot. ``theta_star`` is exposed for evaluation only.

    The env passes θ̂ only when the human declares ``needs_theta_hat = True`` (a human without
    the attribute is assumed to need it); otherwise ``theta_hat`` is None.
    """

    theta_star: np.ndarray

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray | None) -> np.ndarray:
        """The correction u_H at state x, given the robot's action and current estimate."""
        ...


def needs_theta_hat(human: Any) -> bool:
    """Whether ``human`` (a Human or a HumanModel) wants the robot's estimate θ̂."""
    return bool(getattr(human, "needs_theta_hat", True))


@dataclasses.dataclass
class Draws:
    """Everything random about n corrections: candidates (n, K+1, a), the model's extra draws
    (arrays with leading axis n) and the standard-normal noise z (n, a)."""

    candidates: np.ndarray
    noise: np.ndarray
    extra: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.noise)

    def broadcast(self, n: int) -> Draws:
        """One draw shared by n people (a basin map's cells see the same human)."""
        if len(self) != 1:
            raise ValueError(f"only a draw for one person can be shared, got {len(self)}")

        def rep(a: np.ndarray) -> np.ndarray:
            return np.broadcast_to(a, (n, *a.shape[1:]))

        return Draws(
            rep(self.candidates), rep(self.noise), {k: rep(v) for k, v in self.extra.items()}
        )


class HumanModel:
    """How a population of simulated people corrects the robot (see the module docstring).

    Subclasses implement :meth:`choose`; models with more randomness than candidates and noise
    override :meth:`draw_extra`; models whose preference changes over corrections override
    :meth:`preference`. The number of draws never depends on θ̂, so learners given one seed see
    the same candidates and noise (paired runs).
    """

    needs_theta_hat: ClassVar[bool] = False

    def __init__(
        self,
        task: Task,
        sigma: float = 0.0,
        bias: float = 0.0,
        n_candidates: int = DEFAULT_CANDIDATES,
    ) -> None:
        self.task = task
        self.sigma = check_fraction("sigma", sigma)
        self.bias = check_fraction("bias", bias, allow_negative=True)
        self.n_candidates = check_size("n_candidates", n_candidates)

    # ------------------------------------------------------------------ what subclasses give
    def choose(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_star: np.ndarray,
        draws: Draws,
        theta_hat: np.ndarray | None = None,
        k: np.ndarray | int = 0,
    ) -> np.ndarray:
        """The noise-free corrections (n, a) of n people at states x (n, s), robot actions
        u_r (n, a), preferences θ* (n, d) and, for models that need it, θ̂ (n, d); ``k`` is
        each person's correction index in the episode (0 for the first)."""
        raise NotImplementedError

    def draw_extra(self, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
        """The model's own random draws for n corrections, taken between candidates and noise."""
        return {}

    def preference(self, theta_star: np.ndarray, k: np.ndarray | int) -> np.ndarray:
        """The preference people with initial θ* hold at correction ``k`` (default: θ*)."""
        return theta_star

    def same_as(self, other: Any) -> bool:
        """Whether ``other`` answers alike (same class, Task and parameters): a vector env
        asks equal models for all their people in one call."""
        if type(other) is not type(self) or vars(other).keys() != vars(self).keys():
            return False
        for name, mine in vars(self).items():
            theirs = vars(other)[name]
            if isinstance(mine, np.ndarray) or isinstance(theirs, np.ndarray):
                if not np.array_equal(mine, theirs):
                    return False
            elif mine is not theirs and mine != theirs:
                return False
        return True

    # ------------------------------------------------------------------ what callers use
    def draw(self, rng: np.random.Generator, n: int) -> Draws:
        """All random draws for n corrections from one generator."""
        cand = self.task.candidate_actions(rng, n, self.n_candidates)
        extra = self.draw_extra(rng, n)
        z = rng.standard_normal((n, self.task.action_dim))
        return Draws(cand, z, extra)

    def draw_each(self, rngs: Sequence[np.random.Generator]) -> Draws:
        """One correction's draws from each generator, stacked: person b's bytes are those
        ``draw(rngs[b], 1)`` gives. For a Task that keeps ``Task.candidate_actions`` only the
        uniform draws stay per generator; scaling by the bound runs once on the batch."""
        task, k, a = self.task, self.n_candidates, self.task.action_dim
        if type(task).candidate_actions is not Task.candidate_actions or not len(rngs):
            parts = [self.draw(rng, 1) for rng in rngs]
            return _stack(parts, a, k)
        # As ``Task.candidate_actions``: U in [0, 1) filled in place per generator, then
        # −1 + 2·U and the bound over the whole batch (the numbers rng.uniform(−1, 1) gives).
        cand = np.empty((len(rngs), k + 1, a))
        cand[:, 0] = 0.0
        z = np.empty((len(rngs), a))
        own_extra = type(self).draw_extra is not HumanModel.draw_extra
        extras = []
        # each generator's uniforms first (one compiled call for them all where it can), then
        # its extra draws and normals, through rows as views made in one call each
        cand[:, 1:] = uniform_rows(rngs, np.empty((len(rngs), k * a))).reshape(len(rngs), k, a)
        for rng, noise in zip(rngs, list(z), strict=True):
            if own_extra:
                extras.append(self.draw_extra(rng, 1))
            rng.standard_normal(out=noise)
        task._unit_to_box(cand[:, 1:])
        extra = (
            {key: np.concatenate([e[key] for e in extras]) for key in extras[0]} if extras else {}
        )
        return Draws(cand, z, extra)

    def corrections(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_star: np.ndarray,
        draws: Draws,
        theta_hat: np.ndarray | None = None,
        k: np.ndarray | int = 0,
    ) -> np.ndarray:
        """u_H (n, a): the choice plus δ ~ N(ε a_max, (σ a_max)²) from the draws' noise."""
        if self.needs_theta_hat and theta_hat is None:
            raise ValueError(f"{type(self).__name__} teaches relative to θ̂: pass theta_hat")
        pref = self.preference(theta_star, k)
        u = self.choose(x, u_r, pref, draws, theta_hat if self.needs_theta_hat else None, k)
        return perturb(self.task, u, self.sigma, self.bias, Replayed(draws.noise))

    def drawn_corrections(
        self,
        rngs: Sequence[np.random.Generator],
        x: np.ndarray,
        u_r: np.ndarray,
        theta_star: np.ndarray,
        theta_hat: np.ndarray | None = None,
        k: np.ndarray | int = 0,
    ) -> np.ndarray | None:
        """``corrections`` over ``draw_each(rngs)`` (person b's draws from ``rngs[b]``) in one
        pass where the model and its Task offer one, else None, having drawn nothing (then
        draw and choose as usual). Default: None."""
        return None

    def correct(
        self,
        x: np.ndarray,
        u_r: np.ndarray,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        theta_hat: np.ndarray | None = None,
        k: np.ndarray | int = 0,
    ) -> np.ndarray:
        """``corrections`` with fresh draws from ``rng`` for the whole batch."""
        return self.corrections(x, u_r, theta_star, self.draw(rng, len(x)), theta_hat, k)


def _stack(parts: Sequence[Draws], a: int, k: int) -> Draws:
    if not parts:
        return Draws(np.zeros((0, k + 1, a)), np.zeros((0, a)))
    extra = {key: np.concatenate([p.extra[key] for p in parts]) for key in parts[0].extra}
    return Draws(
        np.concatenate([p.candidates for p in parts]),
        np.concatenate([p.noise for p in parts]),
        extra,
    )


class Replayed:
    """A stand-in generator that hands back draws already made (``standard_normal`` or
    ``random``), so the batched choices can take their randomness from ``Draws``."""

    def __init__(self, drawn: np.ndarray) -> None:
        self._drawn = drawn

    def _give(self, shape: tuple[int, ...]) -> np.ndarray:
        if tuple(shape) != self._drawn.shape:
            raise ValueError(f"expected draws of shape {self._drawn.shape}, asked for {shape}")
        return self._drawn

    standard_normal = _give
    random = _give


class SimulatedHuman:
    """One simulated person of a :class:`HumanModel`: the single-sample ``act`` the envs call.

    Built as ``Cls(task, theta_star, rng, **params)``, where ``params`` are those of the class's
    ``model`` (σ, ε, n_candidates and the model's own), so a subclass per model is a factory
    for ``make_human``. It counts its corrections (a changing preference depends on it), and
    ``theta_star`` is always the preference it currently holds.
    """

    model_class: ClassVar[type[HumanModel]]

    def __init__(
        self,
        task: Task,
        theta_star: np.ndarray,
        rng: np.random.Generator,
        *args: Any,
        **params: Any,
    ) -> None:
        self._start(self.model_class(task, *args, **params), theta_star, rng)

    @classmethod
    def of_model(
        cls, model: HumanModel, theta_star: np.ndarray, rng: np.random.Generator
    ) -> SimulatedHuman:
        """A person of an already built ``model``: a vector env's sub-envs share one, so that
        asking them together needs no comparison of their parameters."""
        human = cls.__new__(cls)
        human._start(model, theta_star, rng)
        return human

    def _start(self, model: HumanModel, theta_star: np.ndarray, rng: np.random.Generator) -> None:
        self.model = model
        self.task = model.task
        self.rng = rng
        self.theta_initial = np.asarray(theta_star, dtype=np.float64)
        self.theta_star = self.theta_initial
        self.n_acts = 0

    def __getattr__(self, name: str) -> Any:  # σ, ε, β, K ... read through to the model
        if name == "model":
            raise AttributeError(name)
        return getattr(self.model, name)

    @property
    def needs_theta_hat(self) -> bool:
        return self.model.needs_theta_hat

    def begin(self) -> np.ndarray:
        """Advance to the next correction: its index and the preference held for it."""
        k = self.n_acts
        if type(self.model).preference is HumanModel.preference:  # θ* itself (asked per step)
            self.theta_star = self.theta_initial
        else:
            self.theta_star = self.model.preference(self.theta_initial[None], k)[0]
        self.n_acts += 1
        return np.asarray(k)

    def act(self, x: np.ndarray, u_r: np.ndarray, theta_hat: np.ndarray | None) -> np.ndarray:
        k = self.begin()
        th = None if theta_hat is None else np.asarray(theta_hat, dtype=np.float64)[None]
        x, u_r, theta = x[None], u_r[None], self.theta_initial[None]
        u = self.model.drawn_corrections((self.rng,), x, u_r, theta, th, k)
        if u is not None:
            return u[0]
        draws = self.model.draw(self.rng, 1)
        return self.model.corrections(x, u_r, theta, draws, th, k)[0]

    @classmethod
    def of(cls, model_class: type[HumanModel], name: str | None = None) -> type[SimulatedHuman]:
        """The adapter class for ``model_class`` (``make_human`` builds one for a registered
        model); named ``name`` in the model's module, so that a spec can find it there."""
        adapter = _ADAPTERS.get(model_class)
        if adapter is None:
            name = name or f"{model_class.__name__}Human"
            body = {
                "model_class": model_class,
                "__doc__": model_class.__doc__,
                "__module__": model_class.__module__,
                "__qualname__": name,
            }
            adapter = _ADAPTERS[model_class] = type(name, (cls,), body)
        return adapter


_ADAPTERS: dict[type[HumanModel], type[SimulatedHuman]] = {}
