"""What the natively batched strol-gym envs share: N sub-envs of one single env, stepped together.

A :class:`VectorCorrectionEnv` is a ``gymnasium.vector.VectorEnv`` whose sub-env i behaves like
the single env made with the same arguments (through ``gymnasium.make``, so with its
``TimeLimit``) and reset with the same seed: the same θ*, start, human (candidates and noise
from the sub-env's own generator, drawn in the single env's order), corrections, observations,
rewards and info. Only the draws stay per sub-env (each has its own ``np.random.Generator``);
the human's choice, the dynamics, φ and the bookkeeping run on arrays of all sub-envs.

Conventions are gymnasium's ``SyncVectorEnv`` ones: ``reset(seed=s)`` seeds sub-env i with
s + i; autoreset is ``NEXT_STEP`` (the step after an episode ends resets that sub-env and returns
its first observation with reward 0); info is a dict of arrays, each with its ``_key`` mask, and
the ``features`` dict nested the same way. The contract is the single env's
(``strol_gym.envs.contract``): the draws of a reset are its public batch-first hooks
(``draw_theta_stars``, ``draw_starts``, ``start_override``) called with one generator per
sub-env, and actions, the correction window, observation and info are built by the same
functions; a subclass supplies the batched simulator: placing sub-envs at their start states,
and one step.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from strol_gym import checks
from strol_gym.envs.contract import (
    CorrectionEnv,
    contract_info,
    correcting,
    int_arg,
    observation,
    robot_actions,
)
from strol_gym.humans.population import batched_corrections
from strol_gym.limits import check_size


class VectorCorrectionEnv(VectorEnv):
    """N sub-envs of ``single_env_cls`` (a strol-gym env), batched; see the module docstring."""

    single_env_cls: ClassVar[type]
    # gymnasium declares metadata per instance; a class-level dict is its own convention
    metadata: dict[str, Any] = {  # noqa: RUF012
        "autoreset_mode": AutoresetMode.NEXT_STEP,
        "render_modes": [],
    }
    extra_info: ClassVar[tuple[str, ...]] = ()
    """Info keys the subclass adds (``_step_rows`` and ``_place_rows`` return them)."""

    def __init__(
        self, num_envs: int = 1, max_episode_steps: int | None = None, **kwargs: Any
    ) -> None:
        self.num_envs = check_size("num_envs", int_arg("num_envs", num_envs, 1))
        if max_episode_steps is not None:
            max_episode_steps = int_arg("max_episode_steps", max_episode_steps, 1)
        self.max_episode_steps = max_episode_steps
        if kwargs.get("render_mode") is not None:
            raise ValueError(
                f"render_mode must be None for the vector env, got {kwargs['render_mode']!r}; "
                "render a single env (gymnasium.make) instead"
            )
        # One single env validates the arguments and holds the Task, spaces and simulator model.
        self.template: CorrectionEnv = self.single_env_cls(**kwargs)
        self.task = self.template.task
        self.single_observation_space = self.template.observation_space
        self.single_action_space = self.template.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None
        n, t = self.num_envs, self.task
        # The single env's human maker; with no simulated person (person=None) no step
        # corrects, as in the single env.
        self._make_human = self.template.human_maker()
        self.n_corrections = self.template.n_corrections if self._make_human is not None else 0
        self.action_scale = self.template.action_scale
        self._rngs: list[np.random.Generator | None] = [None] * n
        self.humans: list[Any] = [None] * n
        self.theta_star = np.tile(self.template.theta_star, (n, 1))
        self.theta_hat = np.tile(self.template.initial_theta_hat(), (n, 1))
        self.steps = np.zeros(n, dtype=np.int64)
        self._x = np.zeros((n, t.state_dim))
        self._started = np.zeros(n, dtype=bool)
        self._autoreset = np.zeros(n, dtype=bool)
        self._last_obs: dict[str, np.ndarray] | None = None

    # ------------------------------------------------------------------ subclass hooks
    def _place_rows(self, rows: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, dict]:
        """Put sub-envs ``rows`` at their starts: (the states reached, the extra reset info)."""
        raise NotImplementedError

    def _step_rows(
        self, rows: np.ndarray, u_h: np.ndarray, u_r: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, dict]:
        """One step of sub-envs ``rows``: (next states, terminated, extra info)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ θ̂
    def set_theta_hat(self, theta_hat: np.ndarray) -> None:
        """Every sub-env's estimate θ̂, (N, d): the nominal humans teach relative to it and the
        next observations carry it (``set_theta_hat`` of the single env, per row)."""
        th = np.asarray(theta_hat, dtype=np.float64)
        if th.shape != self.theta_hat.shape or not np.isfinite(th).all():
            raise ValueError(
                f"theta_hat must be finite numbers of shape {self.theta_hat.shape}, "
                f"got shape {th.shape}"
            )
        self.theta_hat[:] = th

    # ------------------------------------------------------------------ reset / step
    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict | None = None
    ) -> tuple[dict, dict]:
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, bool):
            raise checks.ArgumentTypeError(f"seed must be None, an int or {n} seeds, got {seed!r}")
        elif isinstance(seed, int | np.integer):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed must be None, an int or {n} seeds, got {len(seeds)}")
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            rows = np.arange(n)
        else:
            mask = np.asarray(mask)
            if mask.shape != (n,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},)")
            rows = np.flatnonzero(mask)
        overrides = self.template.reset_overrides(options)
        for i in rows:
            if seeds[i] is not None or self._rngs[i] is None:
                self._rngs[i], _ = seeding.np_random(seeds[i])
        self._reset_rows(rows, overrides)
        self._autoreset[rows] = False
        zeros = np.zeros((len(rows), self.task.action_dim))
        fresh = self._observations(rows, zeros)
        if len(rows) == n:
            obs = fresh
        else:  # the other sub-envs keep their last observation, as SyncVectorEnv's do
            last = self._last_obs or {
                k: np.zeros((n, *v.shape[1:]), dtype=v.dtype) for k, v in fresh.items()
            }
            obs = {k: v.copy() for k, v in last.items()}
            for k, v in fresh.items():
                obs[k][rows] = v
        self._last_obs = obs
        info = self._infos(rows, zeros, zeros, np.zeros(len(rows), dtype=bool), self._reset_extra)
        return obs, info

    def _reset_rows(self, rows: np.ndarray, overrides: tuple = (None, None)) -> None:
        theta_override, x_override = overrides
        t = self.template
        # The single env's own draws, in its order per sub-env: θ*, then its start and human
        # generator (each sub-env has its own generator, so all θ* first is the same order).
        rngs = [self._rngs[i] for i in rows]
        theta = t.draw_theta_stars(rngs)
        x0, human_rngs = t.draw_starts(rngs, human_rngs=bool(self.n_corrections))
        if theta_override is not None:
            theta[:] = theta_override
        if x_override is not None:
            x0[:] = t.start_override(x_override)
        self.theta_star[rows] = theta
        # A human that never acts draws nothing: with n_corrections = 0 it is not built.
        if self.n_corrections:
            for k, i in enumerate(rows):
                self.humans[i] = self._make_human(theta[k], human_rngs[k])
        self.theta_hat[rows] = t.initial_theta_hat()
        self.steps[rows] = 0
        self._started[rows] = True
        self._x[rows], self._reset_extra = self._place_rows(rows, x0)

    def step(self, actions: Any) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, dict]:
        n, t = self.num_envs, self.task
        if np.iscomplexobj(actions):  # float64 would drop the imaginary part silently
            raise ValueError("actions must be real numbers")
        try:
            actions = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"actions must be numbers, got {actions!r}") from None
        if actions.shape != (n, t.action_dim):
            raise ValueError(f"actions must have shape ({n}, {t.action_dim}), got {actions.shape}")
        if not self._started.all():
            raise RuntimeError("call reset() before step()")
        done = self._autoreset.copy()
        rows = np.flatnonzero(~done)
        again = np.flatnonzero(done)
        # the stepped rows, as a slice where they are all (cheaper indexing, the same numbers)
        sel: np.ndarray | slice = slice(None) if len(rows) == n else rows
        a = actions[sel]
        if not np.isfinite(a).all():
            bad = rows[~np.isfinite(a).all(axis=1)]
            raise ValueError(f"actions must be finite, got {actions[bad[0]]} in row {bad[0]}")
        u_r = np.zeros((n, t.action_dim))
        u_h = np.zeros((n, t.action_dim))
        u_r[sel] = robot_actions(a, self.action_scale)
        corr = np.zeros(n, dtype=bool)
        corr[sel] = correcting(self.steps[sel], self.n_corrections)
        act = np.flatnonzero(corr)
        if len(act):
            humans = [self.humans[i] for i in act]
            u = batched_corrections(humans, self._x[act], u_r[act], self.theta_hat[act])
            if u.shape != (len(act), t.action_dim) or not np.isfinite(u).all():
                raise ValueError(
                    f"the humans' corrections must be {t.action_dim} finite numbers each"
                )
            u_h[act] = u
            self.theta_star[act] = [h.theta_star for h in humans]
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        extra: dict[str, Any] = {}
        if len(rows):
            x, term, extra = self._step_rows(rows, u_h[rows], u_r[rows])
            self._x[sel] = x
            self.steps[sel] += 1
            terminated[sel] = term
            if self.max_episode_steps is not None:
                truncated[sel] = self.steps[sel] >= self.max_episode_steps
        if len(again):
            self._reset_rows(again)
            u_r[again] = 0.0
            extra = self._merge_extra(extra, rows, again)
        phi = t.features(self._x)
        rewards = np.einsum("nd,nd->n", phi, self.theta_star)
        rewards[again] = 0.0
        self._autoreset = terminated | truncated
        everyone = np.arange(n)
        obs = self._observations(everyone, u_h, phi)
        self._last_obs = obs
        info = self._infos(everyone, u_h, u_r, corr, extra, phi)
        return obs, rewards, terminated, truncated, info

    def _merge_extra(self, extra: dict, rows: np.ndarray, again: np.ndarray) -> dict:
        """The extra info of stepped ``rows`` and of autoreset ``again`` in one set of arrays."""
        out = {}
        for key in self.extra_info:
            first = self._reset_extra[key]
            arr = np.zeros((self.num_envs, *first.shape[1:]), dtype=first.dtype)
            if len(rows):
                arr[rows] = extra[key]
            arr[again] = first
            out[key] = arr
        return out

    # ------------------------------------------------------------------ observation and info
    def _observations(
        self, rows: np.ndarray, u_h: np.ndarray, phi: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        x = self._x[rows]
        if phi is None:
            phi = self.task.features(x)
        return observation(x, u_h, self.theta_hat[rows], phi)

    def _infos(
        self,
        rows: np.ndarray,
        u_h: np.ndarray,
        u_r: np.ndarray,
        is_correction: np.ndarray,
        extra: dict[str, np.ndarray],
        phi: np.ndarray | None = None,
    ) -> dict[str, Any]:
        """Info as ``SyncVectorEnv`` batches the single env's: arrays over all N sub-envs with
        ``_key`` masks true for ``rows`` (the sub-envs this call reset or stepped)."""
        n = self.num_envs
        x = self._x[rows]
        if phi is None:
            phi = self.task.features(x)
        mask = np.zeros(n, dtype=bool)
        mask[rows] = True

        def full(values: np.ndarray) -> np.ndarray:
            if len(rows) == n:
                return np.array(values)
            out = np.zeros((n, *values.shape[1:]), dtype=values.dtype)
            out[rows] = values
            return out

        info: dict[str, Any] = {}
        features: dict[str, Any] = {}
        for j, name in enumerate(self.task.feature_names):
            features[name], features[f"_{name}"] = full(phi[:, j]), mask.copy()
        values = contract_info(
            features,
            full(phi),
            full(u_h),
            full(u_r),
            full(self.theta_star[rows]),
            full(self.theta_hat[rows]),
            full(is_correction),
        )
        values.update((key, full(value)) for key, value in extra.items())
        for key, value in values.items():
            info[key], info[f"_{key}"] = value, mask.copy()
        return info

    def close_extras(self, **kwargs: Any) -> None:
        self.template.close()
