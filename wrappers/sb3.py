"""stable-baselines3 on a gymnasium vector env, in one process (no subprocesses, no copies).

``SB3VecEnv(gymnasium.make_vec("StROL-Robot-v0", num_envs=N))`` is an SB3 ``VecEnv``; so is
``SB3VecEnv(SyncVectorEnv([...]))`` over wrapped sub-envs. SB3 resets a sub-env in the step that
ends its episode and hands the last observation over in ``info["terminal_observation"]``.
gymnasium's vector envs do that too in ``SAME_STEP`` autoreset (the last observation in
``info["final_obs"]``), and reset on the following step in ``NEXT_STEP``: there the adapter
resets the sub-envs that ended itself (``reset(options={"reset_mask": ...})``), so SB3 sees its
own convention either way.

Attributes (``get_attr``, ``set_attr``, ``env_method``, ``env_is_wrapped``) follow SB3's
per-sub-env contract, which gymnasium leaves undefined for vector envs (a ``VectorWrapper`` does
not forward attributes), so the adapter defines it: the ``VectorWrapper`` chain is searched from
the outside in, then the sub-envs with their own wrappers (where the base holds them, as
``SyncVectorEnv`` does), then the base vector env. A value found on a vector wrapper or the base
is shared by all sub-envs: an array whose leading axis has ``num_envs`` rows gives sub-env i
row i, anything else is the same object for every index, and setting or calling it for only
some of the sub-envs raises ``ValueError`` (it would change the others too).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from gymnasium.vector import VectorEnv, VectorWrapper

try:
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices
except ImportError as e:  # an extra, not the core: say which
    raise ImportError(
        "strol_gym.wrappers.sb3 needs stable-baselines3: pip install 'strol-gym[sb3]'"
    ) from e

AUTORESET_MODES = ("NextStep", "SameStep")
"""The gymnasium autoreset modes the adapter bridges (``DISABLED`` leaves resets to the user)."""


class SB3VecEnv(VecEnv):
    """A gymnasium ``VectorEnv`` (autoreset ``NEXT_STEP`` or ``SAME_STEP``) as an SB3 ``VecEnv``."""

    def __init__(self, env: VectorEnv) -> None:
        if not isinstance(env, VectorEnv):
            raise TypeError(f"env must be a gymnasium VectorEnv, got {type(env).__name__}")
        mode = env.metadata.get("autoreset_mode")
        mode = "NextStep" if mode is None else str(getattr(mode, "value", mode))
        if mode not in AUTORESET_MODES:
            raise ValueError(f"env's autoreset mode must be NEXT_STEP or SAME_STEP, got {mode}")
        self.env = env
        self.same_step = mode == "SameStep"
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self):
        seeds = [s for s in self._seeds if s is not None]
        seed = [int(s) for s in seeds] if len(seeds) == self.num_envs else None
        # VectorEnv.reset is typed seed: int | None, yet vector envs (ours, Sync/Async) take
        # one seed per sub-env as a list.
        obs, info = self.env.reset(
            seed=seed,  # type: ignore[arg-type]  # a list: see above
            options=self._options[0] or None,
        )
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = self._per_env(info, np.ones(self.num_envs, dtype=bool))
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, reward, terminated, truncated, info = self.env.step(self._actions)
        done = np.asarray(terminated) | np.asarray(truncated)
        if self.same_step:  # obs and info are already the reset's for the sub-envs that ended
            info = dict(info)
            final_obs, final_info = info.pop("final_obs", None), info.pop("final_info", {})
            info.pop("_final_obs", None)
            info.pop("_final_info", None)
            infos = self._per_env(info, ~done)
            ended = self._per_env(final_info, done)
            reset_infos = self._per_env(info, done)
            for i in np.flatnonzero(done).tolist():
                infos[i] = ended[i]
                infos[i]["terminal_observation"] = self._row(final_obs, i)
                self.reset_infos[i] = reset_infos[i]
        else:
            infos = self._per_env(info, np.ones(self.num_envs, dtype=bool))
            final_obs = obs
            for i in np.flatnonzero(done).tolist():
                infos[i]["terminal_observation"] = self._row(final_obs, i)
            if done.any():
                obs, reset_info = self.env.reset(options={"reset_mask": done})
                for i, extra in enumerate(self._per_env(reset_info, done)):
                    if done[i]:
                        self.reset_infos[i] = extra
        for i in np.flatnonzero(done).tolist():
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, np.asarray(reward, dtype=np.float32), done, infos

    @staticmethod
    def _row(obs: Any, i: int) -> Any:
        """Sub-env i's observation out of a batched one (a dict of arrays, an array, or
        gymnasium's ``final_obs``: an object array of sub-env observations)."""
        if isinstance(obs, dict):
            return {k: SB3VecEnv._row(v, i) for k, v in obs.items() if not k.startswith("_")}
        row = obs[i]
        if isinstance(row, dict):
            return {k: np.array(v, copy=True) for k, v in row.items()}
        return np.array(row, copy=True)

    @staticmethod
    def _per_env(info: dict, rows: np.ndarray) -> list[dict]:
        """Gymnasium's batched info (arrays with ``_key`` masks) as one dict per sub-env."""
        out: list[dict] = [{} for _ in range(len(rows))]
        for key, value in info.items():
            if key.startswith("_"):
                continue
            mask = info.get(f"_{key}", rows)
            nested = SB3VecEnv._per_env(value, rows) if isinstance(value, dict) else None
            for i in np.flatnonzero(mask & rows).tolist():
                out[i][key] = value[i] if nested is None else nested[i]
        return out

    def close(self) -> None:
        self.env.close()

    # ------------------------------------------------------------------ SB3's attribute plumbing
    def _holder(self, name: str) -> VectorEnv | None:
        """The vector wrapper or base that holds ``name``, or None when the sub-envs hold it."""
        env: Any = self.env
        while isinstance(env, VectorWrapper):
            if name in vars(env) or _defined_below_vector_wrapper(type(env), name):
                return env
            env = env.env
        if self._sub_envs(env) is not None:
            try:
                for sub in self._sub_envs(env) or ():
                    sub.get_wrapper_attr(name)
                return None
            except AttributeError:
                pass
        if not hasattr(env, name):
            raise AttributeError(f"no vector wrapper, sub-env or base env has {name!r}")
        return env

    @staticmethod
    def _sub_envs(base: Any) -> list[Any] | None:
        """The sub-envs a base vector env holds as objects (``SyncVectorEnv.envs``), else None."""
        envs = getattr(base, "envs", None)
        if isinstance(envs, list | tuple) and all(hasattr(e, "get_wrapper_attr") for e in envs):
            return list(envs)
        return None

    def _base_envs(self) -> list[Any] | None:
        return self._sub_envs(self.env.unwrapped)

    def _split(self, value: Any, indices: list[int]) -> list[Any]:
        """A shared value per index: row i of a ``num_envs``-row array, else the value itself."""
        if isinstance(value, np.ndarray) and value.ndim >= 1 and len(value) == self.num_envs:
            return [value[i] for i in indices]
        return [value for _ in indices]

    def _all_or_raise(self, name: str, indices: list[int], what: str) -> None:
        if sorted(set(indices)) != list(range(self.num_envs)):
            raise ValueError(
                f"{what} {name!r} is shared by all {self.num_envs} sub-envs (it is held by the "
                f"vector env, not by each sub-env), so indices must be all of them, got {indices}"
            )

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        idx = list(self._get_indices(indices))
        holder = self._holder(attr_name)
        if holder is None:
            subs = self._base_envs() or []
            return [subs[i].get_wrapper_attr(attr_name) for i in idx]
        return self._split(getattr(holder, attr_name), idx)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        idx = list(self._get_indices(indices))
        holder = self._holder(attr_name)
        if holder is None:
            subs = self._base_envs() or []
            for i in idx:
                subs[i].set_wrapper_attr(attr_name, value)
            return
        old = getattr(holder, attr_name)
        if isinstance(old, np.ndarray) and old.ndim >= 1 and len(old) == self.num_envs:
            new = old.copy()
            new[idx] = value
            setattr(holder, attr_name, new)
            return
        self._all_or_raise(attr_name, idx, "attribute")
        setattr(holder, attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        idx = list(self._get_indices(indices))
        if method_name == "get_wrapper_attr":  # gymnasium's own accessor, on every level
            return self.get_attr(method_args[0], indices=idx)
        if method_name == "set_wrapper_attr":
            name, value = method_args[:2]
            self.set_attr(name, value, indices=idx)
            return [True for _ in idx]
        holder = self._holder(method_name)
        if holder is None:
            subs = self._base_envs() or []
            calls = [subs[i].get_wrapper_attr(method_name) for i in idx]
            return [call(*method_args, **method_kwargs) for call in calls]
        self._all_or_raise(method_name, idx, "method")
        method: Callable[..., Any] = getattr(holder, method_name)
        return self._split(method(*method_args, **method_kwargs), idx)

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        from stable_baselines3.common.env_util import is_wrapped

        idx = list(self._get_indices(indices))
        env: Any = self.env
        while isinstance(env, VectorWrapper):
            if isinstance(env, wrapper_class):
                return [True for _ in idx]
            env = env.env
        subs = self._sub_envs(env)
        if subs is None:
            return [False for _ in idx]
        return [is_wrapped(subs[i], wrapper_class) for i in idx]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]


def _defined_below_vector_wrapper(cls: type, name: str) -> bool:
    """Whether a ``VectorWrapper`` subclass defines ``name`` itself (not gymnasium's forwarding)."""
    for klass in cls.__mro__:
        if klass is VectorWrapper:
            return False
        if name in vars(klass):
            return True
    return False
