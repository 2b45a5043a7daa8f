"""The env contract: what every strol-gym env shares (the corrective human, θ̂, actions, the
correction window, observation and info), batch-first, for the single env (one row) and the
vector env (N rows, ``strol_gym.envs.vector``).

Every env is a Task plus a simulator (MuJoCo arm, highway-env cars, ...). :class:`CorrectionEnv`
holds the part that is the same whatever simulates the Task, so the envs agree on the contract
the learners, the wrapper and the benchmark rely on:

- observation ``{"state": x, "correction": u_H, "theta_hat": θ̂, "phi": φ(x)}``;
- info ``features``, ``phi``, ``correction``, ``robot_action``, ``theta_star`` (the human's
  *current* preference), ``theta_hat``, ``is_correction``; an env whose corrections span
  several steps adds ``correction_state`` (the state where the correction began);
- reward R(x', θ*) = θ*·φ(x');
- the simulated person given as one ``person=`` argument (``strol_gym.humans.spec``: omitted,
  the env's ``default_person``; a name; a :class:`~strol_gym.humans.spec.HumanSpec` or a dict
  of its fields; ``None``: no simulated person, the corrections come from elsewhere or none
  come), kept as the person as used (``person_spec``);
- episodes end through gymnasium's ``TimeLimit`` (``gymnasium.make``); an env built directly
  truncates itself only when given ``max_episode_steps``. One rule, one place: ``_truncated``.

It is a mixin, placed before the simulator's base class (``gym.Env`` or highway-env's
``AbstractEnv``), and a template: it owns ``__init__``, ``reset`` and ``step``, and an env
supplies hooks around its simulator:

- ``_setup()``: build the simulator and the spaces (the shared arguments are checked by then);
- ``_make_task(task)``: the ``task`` argument as a Task (default: a name or Task of ``task_cls``);
- ``draw_theta_stars(rngs)``: θ* per generator, (n, d) (default: from the prior);
- ``draw_starts(rngs)``: the start states (n, state_dim) and the humans' generators, each
  drawn from its generator after θ* (default: ``task.sample_starts``, the human drawing from
  the episode's generator);
- ``start_override(x0)``: a start given as ``reset(options={"state": ...})``, made admissible;
- ``_place_start(x0)``: put the simulator at x0 and return its state;
- ``_advance(u_h, u_r)``: one step; returns the new state and the env's own info keys;
- ``_start_info()`` and ``_terminated()``: the env's own info at reset, and whether the episode
  ended (default never);
- ``_transition(u_r)``: the whole step between the robot's action and the reward, for an env
  whose corrections come out of its physics (the study env, where a person pushes) rather than
  from the human's ``act`` (default: ``_human_correction`` then ``_advance``).

The draw hooks and ``start_override`` are public and batch-first: the single env calls them
with one generator, the vector env (``VectorCorrectionEnv``) with one per sub-env, and both
build observation and info with the functions below (:func:`observation`, :func:`contract_info`,
:func:`robot_actions`, :func:`correcting`), so a sub-env of the vector env is the single env.

An env with more arguments than the shared ones takes them in its own ``__init__``, stores
them and passes the rest on to ``CorrectionEnv.__init__``.
``docs/extending.md`` shows a complete small env.
"""

from __future__ import annotations

import inspect
import math
from typing import TYPE_CHECKING, Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from strol_gym import checks
from strol_gym.humans import Human, HumanFactory, needs_theta_hat
from strol_gym.humans.population import HumanMaker
from strol_gym.humans.spec import (
    DEFAULT_HUMAN,
    DEFAULT_PERSON,
    PERSON_ARGUMENTS,
    HumanSpec,
    person_spec,
)
from strol_gym.priors import Prior, check_theta_range, make_prior, sample_each
from strol_gym.tasks import make_task
from strol_gym.tasks.base import Task, vector_arg

RESET_OPTIONS = ("theta_star", "state")
_REAL = (np.dtype(np.float32), np.dtype(np.float64))


def int_arg(name: str, value: Any, low: int, high: int | None = None) -> int:
    """An integer argument in [low, high], else ValueError naming it and the range. An int
    itself: a float (even 2.0) is refused, as a count or a size given as 2.5 would be."""
    if isinstance(value, float | np.floating):
        value = str(value)  # refused below with the same words as any non-integer
    return int(checks.number(name, value, low=low, high=high, integer=True))


def robot_actions(actions: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Actions in [−1, 1] (one row or N) as u_R in task units: out of range clips."""
    return np.minimum(np.maximum(actions, -1.0), 1.0) * scale


def correcting(steps: Any, n_corrections: int) -> Any:
    """The correction window: the human corrects during the first ``n_corrections`` steps of
    an episode (``steps`` an int, or an array of N sub-envs' counts)."""
    return steps < n_corrections


def observation(
    x: np.ndarray, u_h: np.ndarray, theta_hat: np.ndarray, phi: np.ndarray
) -> dict[str, np.ndarray]:
    """The contract's observation of one state (1-D arrays) or N (2-D), as float32 copies
    (``np.array``: the cheapest spelling of the copy on a few numbers)."""
    f32 = np.float32
    return {
        "state": np.array(x, dtype=f32),
        "correction": np.array(u_h, dtype=f32),
        "theta_hat": np.array(theta_hat, dtype=f32),
        "phi": np.array(phi, dtype=f32),
    }


def contract_info(
    features: Any,
    phi: np.ndarray,
    u_h: np.ndarray,
    u_r: np.ndarray,
    theta_star: np.ndarray,
    theta_hat: np.ndarray,
    is_correction: Any,
) -> dict[str, Any]:
    """The info keys every env provides, in their order, for one row or N: ``features`` (φ by
    feature name), φ, u_H, u_R, the human's current θ*, θ̂ and whether the step corrected.
    Values as given: the single env passes copies, the vector env arrays over its sub-envs."""
    return {
        "features": features,
        "phi": phi,
        "correction": u_h,
        "robot_action": u_r,
        "theta_star": theta_star,
        "theta_hat": theta_hat,
        "is_correction": is_correction,
    }


class RenderModes(list):
    """An env's ``metadata["render_modes"]``. ``gymnasium.make`` asks whether ``render_mode``
    is one of them before the env can check it, and a non-string then fails inside gymnasium
    with an AttributeError; asking here raises the env's own ValueError instead."""

    def __contains__(self, mode: object) -> bool:
        if not isinstance(mode, str):
            raise ValueError(f"render_mode must be None or one of {list(self)}, got {mode!r}")
        return super().__contains__(mode)


def render_metadata(fps: int) -> dict[str, Any]:
    """An env's ``metadata``: it renders "human" (a window) and "rgb_array" at ``fps``."""
    return {"render_modes": RenderModes(["human", "rgb_array"]), "render_fps": fps}


class CorrectionEnv:
    """The human-correction half of a strol-gym env (a mixin and template; see the module
    docstring). Subclasses set ``env_id``, ``task_cls`` and the defaults, and fill the hooks."""

    metadata: dict[str, Any]
    task: Any
    theta_hat: np.ndarray
    human: Human | None
    steps: int
    _x: np.ndarray
    render_mode: str | None
    if TYPE_CHECKING:  # gym.Env's, which every strol-gym env also is (never defined here)
        np_random: np.random.Generator

        def close(self) -> None: ...

        def render(self) -> Any: ...

    env_id: ClassVar[str] = ""
    # Task is abstract: the base's placeholder lets make_task(task, of=Task) take any Task;
    # each env names its own class, called with no arguments for the default Task.
    task_cls: ClassVar[type[Task]] = Task  # type: ignore[type-abstract]  # see above
    default_corrections: ClassVar[int] = 5
    """``n_corrections`` when not given."""
    default_size: ClassVar[tuple[int, int]] = (480, 360)
    """Frame ``width`` and ``height`` (pixels) when not given."""
    default_person: ClassVar[str | HumanFactory] = DEFAULT_HUMAN
    """The person when ``person=`` is omitted (or a dict of its fields names none)."""

    def __init__(
        self,
        person: Any = DEFAULT_PERSON,
        prior: str | Prior | Any | None = "bimodal",
        n_corrections: int | None = None,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        width: int | None = None,
        height: int | None = None,
        task: Any = None,
        **unknown: Any,
    ) -> None:
        """The shared arguments (the env's docstring lists them); ``None`` for
        ``n_corrections``, ``width`` or ``height`` means the env's default, for ``prior`` the
        Task's own prior. ``person``: ``strol_gym.humans.spec`` (omitted: ``default_person``)."""
        self._configure(
            task,
            unknown,
            prior=prior,
            person=person,
            n_corrections=self.default_corrections if n_corrections is None else n_corrections,
            render_mode=render_mode,
            max_episode_steps=max_episode_steps,
        )
        self.render_mode = render_mode
        w, h = self.default_size
        self.width = int_arg("width", w if width is None else width, 16, 4096)
        self.height = int_arg("height", h if height is None else height, 16, 4096)
        self._x = np.zeros(self.task.state_dim)
        self._setup()
        # A simulator that resets itself while it is built (highway-env does) has not started
        # the caller's episode: step() before the caller's reset() raises in every env.
        self._started = False

    # ------------------------------------------------------------------ the env's hooks
    def _setup(self) -> None:
        """Build the simulator and set ``observation_space`` and ``action_space``."""
        raise NotImplementedError

    def draw_theta_stars(self, rngs: list[np.random.Generator]) -> np.ndarray:
        """Each episode's θ*, (len(rngs), d): the first draw from its generator (default: from
        the prior)."""
        return sample_each(self.task.prior, rngs)

    def draw_starts(
        self, rngs: list[np.random.Generator], human_rngs: bool = True
    ) -> tuple[np.ndarray, list[Any]]:
        """Start states (len(rngs), state_dim) and the humans' generators, each drawn from its
        episode's generator after θ* (default: ``task.sample_starts``; the human draws from the
        episode's generator itself). ``human_rngs=False``: no human will act, an env may skip
        building their generators."""
        return self.task.sample_starts(rngs), list(rngs)

    def start_override(self, x0: np.ndarray) -> np.ndarray:
        """A start state given as ``reset(options={"state": ...})``, made admissible."""
        return x0

    def _place_start(self, x0: np.ndarray) -> np.ndarray:
        """Put the simulator at x0; returns its state (default: x0 itself)."""
        return x0

    def _advance(self, u_h: np.ndarray, u_r: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        """One step with the human's and the robot's actions: (new state, the env's info)."""
        raise NotImplementedError

    def _start_info(self) -> dict[str, Any]:
        """The env's own info keys after ``reset``."""
        return {}

    def _terminated(self) -> bool:
        """Whether the episode ended (a crash, say); default never."""
        return False

    # ------------------------------------------------------------------ the template
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        gym.Env.reset(self, seed=seed)  # type: ignore[arg-type]  # a mixin: self is a gym.Env too
        theta_override, x_override = self.reset_overrides(options)
        rngs = [self.np_random]
        theta_star = self.draw_theta_stars(rngs)[0]
        x0s, human_rngs = self.draw_starts(rngs)
        x0, human_rng = x0s[0], human_rngs[0]
        if theta_override is not None:
            theta_star = theta_override
        if x_override is not None:
            x0 = self.start_override(x_override)
        self._start_episode(theta_star, human_rng)
        self._x = self._place_start(x0)
        zeros = np.zeros(self.task.action_dim)
        phi = self.task.features(self._x)
        obs = self._obs(zeros, phi)
        info = self._info(phi, zeros, zeros, False)
        info.update(self._start_info())
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        u_r = self._robot_action(action)
        if not self._started:
            raise RuntimeError("call reset() before step()")
        u_h, u_r, is_correction, extra = self._transition(u_r)
        phi = self.task.features(self._x)
        reward = float(phi @ self.theta_star)
        terminated = self._terminated()
        truncated = (not terminated) and self._truncated()
        obs = self._obs(u_h, phi)
        info = self._info(phi, u_h, u_r, is_correction)
        info.update(extra)
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, info

    def _transition(self, u_r: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, dict[str, Any]]:
        """One step from the robot's action u_R: the human corrects (the first
        ``n_corrections`` steps), the simulator advances, ``steps`` and the state move on.
        Returns (u_H, the robot action applied, is_correction, the env's info keys). An env
        whose corrections come from its physics (a person pushing) replaces this."""
        u_h, is_correction = self._human_correction(self._x, u_r)
        x, extra = self._advance(u_h, u_r)
        self.steps += 1
        self._x = x
        return u_h, u_r, is_correction, extra

    def _configure(
        self,
        task: Task | str | None,
        unknown: dict[str, Any],
        *,
        prior: str | Prior | Any | None,
        person: Any,
        n_corrections: int,
        render_mode: str | None,
        max_episode_steps: int | None = None,
    ) -> None:
        """Validate the shared keyword arguments; each error names the argument and its range."""
        if unknown:
            takes = sorted(
                {
                    p
                    for cls in type(self).__mro__
                    if "__init__" in vars(cls) and issubclass(cls, CorrectionEnv)
                    for p in inspect.signature(vars(cls)["__init__"]).parameters
                    if p not in ("self", "unknown", "kwargs")
                }
            )
            moved = [k for k in sorted(unknown) if k in PERSON_ARGUMENTS]
            hint = (
                f" ({', '.join(moved)}: the person's, given as person=HumanSpec(name, sigma=..., "
                "bias=..., beta=..., kwargs={...}) or a dict of those fields)"
                if moved
                else ""
            )
            raise ValueError(
                f"unknown argument(s) {sorted(unknown)}; {self.env_id} takes {takes}{hint}"
            )
        task = self._make_task(task)
        self.task = task.with_prior(
            task.prior if prior is None else make_prior(prior, task.prior_modes)
        )
        self.person_spec = self.resolve_person(person)
        """The person as used (every parameter it takes, defaults filled in), None for none."""
        self.n_corrections = int_arg("n_corrections", n_corrections, 0)
        if max_episode_steps is not None:
            max_episode_steps = int_arg("max_episode_steps", max_episode_steps, 1)
        self.max_episode_steps = max_episode_steps
        modes = self.metadata["render_modes"]
        if render_mode is not None and render_mode not in modes:
            raise ValueError(f"render_mode must be None or one of {modes}, got {render_mode!r}")
        self.action_scale = np.asarray(self.task.robot_action_bound, dtype=np.float64)
        """u_R per unit of action (the Task's per-axis bound): u_R = clip(action, −1, 1) · this."""
        self._u_scale_l = self.action_scale.tolist()
        self._a_shape = (self.task.action_dim,)
        self.theta_hat = self.initial_theta_hat()
        self.theta_star = self.task.prior.mean.copy()
        self.human = None
        self._started = False
        self.steps = 0

    def _make_task(self, task: Task | str | None) -> Task:
        """The ``task`` argument as a Task of ``task_cls`` (None: the env's default Task)."""
        if task is None:
            # every concrete Task defaults all its fields (Task itself is abstract)
            return self.task_cls()  # type: ignore[call-arg]  # see the line above
        return make_task(task, of=self.task_cls)

    @classmethod
    def resolve_person(cls, person: Any) -> HumanSpec | None:
        """The ``person=`` argument as the env uses it (a human model's: ``HumanSpec.as_used``),
        without building the env; ValueError naming what it does not use."""
        spec = person_spec(person, cls.default_person)
        return None if spec is None else spec.as_used()

    def human_maker(self) -> HumanMaker | None:
        """What builds the episode's human from θ* and a generator (None: no simulated one)."""
        return None if self.person_spec is None else self.person_spec.maker(self.task)

    def _observation_space(self, state: spaces.Box, phi: spaces.Box | None = None) -> spaces.Dict:
        """The shared observation space: ``state`` as given; φ unbounded unless given."""
        f32 = np.float32
        t = self.task
        return spaces.Dict(
            {
                "state": state,
                "correction": spaces.Box(-np.inf, np.inf, shape=(t.action_dim,), dtype=f32),
                "theta_hat": spaces.Box(-np.inf, np.inf, shape=(t.dim,), dtype=f32),
                "phi": phi or spaces.Box(-np.inf, np.inf, shape=(t.dim,), dtype=f32),
            }
        )

    # ------------------------------------------------------------------ θ*, θ̂ and the human
    @property
    def theta_star(self) -> np.ndarray:
        """The human's current preference θ* (what rewards and evaluation use)."""
        human = getattr(self, "human", None)
        if human is not None:
            return np.asarray(human.theta_star, dtype=np.float64)
        return self._theta_star

    @theta_star.setter
    def theta_star(self, value: np.ndarray) -> None:
        self._theta_star = np.asarray(value, dtype=np.float64)

    def initial_theta_hat(self) -> np.ndarray:
        """θ̂0, an episode's first estimate: the mean of the Task's prior modes (a copy of the
        mean taken once per Task: every reset asks)."""
        memo = self.__dict__.get("_theta_hat0_memo")
        if memo is None or memo[0] is not self.task:
            modes = np.asarray(self.task.prior_modes, dtype=np.float64)
            memo = self.__dict__["_theta_hat0_memo"] = (self.task, modes.mean(axis=0))
        return memo[1].copy()

    def set_theta_hat(self, theta_hat: np.ndarray) -> None:
        """The robot's current estimate θ̂: the nominal human teaches relative to it, and the
        next observation carries it. Reset restores the bimodal prior modes' mean."""
        self.theta_hat = checks.vector("theta_hat", theta_hat, self.task.dim)

    def _make_human(self, theta_star: np.ndarray, rng: np.random.Generator) -> Human | None:
        # One maker per (spec, Task): a reset then costs a person, not a signature lookup.
        spec, task = self.person_spec, self.task
        made_for = self.__dict__.get("_maker_for")
        if made_for is None or made_for[0] is not spec or made_for[1] is not task:
            self._maker, self._maker_for = self.human_maker(), (spec, task)
        return None if self._maker is None else self._maker(theta_star, rng)

    def _start_episode(self, theta_star: np.ndarray, human_rng: np.random.Generator) -> None:
        """A new episode's θ*, θ̂0 and human (``reset`` calls it after drawing θ*)."""
        self.human = None
        self.theta_star = theta_star
        self.theta_hat = self.initial_theta_hat()
        self.human = self._make_human(theta_star, human_rng)
        self._started = True
        self.steps = 0

    def reset_overrides(self, options: dict | None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """``reset(options={"theta_star": ..., "state": ...})``: checked overrides or None."""
        options = checks.mapping("options", options, f"a dict with keys among {RESET_OPTIONS}")
        bad = set(options) - set(RESET_OPTIONS)
        if bad:
            raise ValueError(f"unknown reset option(s) {sorted(bad)}; valid: {RESET_OPTIONS}")
        theta_star = options.get("theta_star")
        state = options.get("state")
        if theta_star is not None:
            theta_star = vector_arg("theta_star", theta_star, self.task.dim)
            check_theta_range("theta_star", theta_star)
        return (
            theta_star,
            None if state is None else vector_arg("state", state, self.task.state_dim),
        )

    # ------------------------------------------------------------------ step helpers
    def _robot_action(self, action: Any) -> np.ndarray:
        """The action in [−1, 1] as u_R in task units. Out of range clips; NaN/inf raises."""
        if type(action) is np.ndarray and action.dtype in _REAL and action.shape == self._a_shape:
            # The common case (an agent's float array) in plain floats: numpy's per-call cost
            # dominates on a few numbers, every step. The same IEEE operations as below.
            values = action.tolist()
            if not all(map(math.isfinite, values)):
                raise ValueError(f"action must be finite, got {action}")
            return np.array(
                [
                    (1.0 if v > 1.0 else (-1.0 if v < -1.0 else v)) * k
                    for v, k in zip(values, self._u_scale_l, strict=True)
                ]
            )
        try:
            shape = np.shape(action)
        except ValueError:  # a ragged sequence
            raise ValueError(
                f"action must be {self.task.action_dim} numbers, got {action!r:.80}"
            ) from None
        if shape != (self.task.action_dim,):
            raise ValueError(f"action must have shape ({self.task.action_dim},), got {shape}")
        if np.iscomplexobj(action):  # float64 would drop the imaginary part silently
            raise ValueError(f"action must be real numbers, got {action}")
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"action must be numbers, got {action!r}") from None
        # Checked in plain floats: numpy's per-call cost dominates on a few numbers, every step.
        values = a.tolist()
        if not all(map(math.isfinite, values)):
            raise ValueError(f"action must be finite, got {action}")
        return robot_actions(a, self.action_scale)

    def _human_correction(self, x: np.ndarray, u_r: np.ndarray) -> tuple[np.ndarray, bool]:
        """(u_H, is_correction): the human's correction during the first ``n_corrections``
        steps, checked to be ``action_dim`` finite numbers; zeros afterwards. θ̂ goes only to a
        human who declares it needs it."""
        if self.human is None or not correcting(self.steps, self.n_corrections):
            return np.zeros(self.task.action_dim), False
        theta_hat = self.theta_hat if needs_theta_hat(self.human) else None
        u_h = np.asarray(self.human.act(x, u_r, theta_hat), dtype=np.float64)
        # finiteness in plain floats: numpy's per-call cost dominates on a few numbers
        if u_h.shape != self._a_shape or not all(map(math.isfinite, u_h.tolist())):
            raise ValueError(
                f"the human's correction must be {self.task.action_dim} finite numbers, got {u_h}"
            )
        return u_h, True

    def _truncated(self) -> bool:
        """Self-truncation of a directly built env given ``max_episode_steps``."""
        return self.max_episode_steps is not None and self.steps >= self.max_episode_steps

    def _obs(self, u_h: np.ndarray, phi: np.ndarray) -> dict[str, np.ndarray]:
        return observation(self._x, u_h, self.theta_hat, phi)

    def _info(
        self, phi: np.ndarray, u_h: np.ndarray, u_r: np.ndarray, is_correction: bool
    ) -> dict[str, Any]:
        """The info keys every strol-gym env provides; envs add their own on top."""
        return contract_info(
            dict(zip(self.task.feature_names, phi.tolist(), strict=True)),
            phi,
            np.array(u_h, dtype=np.float64),
            np.array(u_r, dtype=np.float64),
            self.theta_star.copy(),
            self.theta_hat.copy(),
            bool(is_correction),
        )
