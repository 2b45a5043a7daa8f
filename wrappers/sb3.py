"""stable-baselines3 on a strol-gym vector env, in one process (no subprocesses, no copies).

``SB3VecEnv(gymnasium.make_vec("StROL-Robot-v0", num_envs=N))`` is an SB3 ``VecEnv``. SB3 resets
a sub-env in the step that ends its episode and hands the last observation over in
``info["terminal_observation"]``; gymnasium's vector envs (``NEXT_STEP`` autoreset) reset it
on the following step. The adapter bridges the two: after a step it resets the sub-envs that
ended (``reset(options={"reset_mask": ...})``), so SB3 sees its own convention. Any
``NEXT_STEP`` vector env that accepts ``reset_mask`` works (gymnasium's ``SyncVectorEnv`` too).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.vector import VectorEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices


class SB3VecEnv(VecEnv):
    """A gymnasium ``VectorEnv`` (autoreset ``NEXT_STEP``) as a stable-baselines3 ``VecEnv``."""

    def __init__(self, env: VectorEnv) -> None:
        mode = env.metadata.get("autoreset_mode")
        if mode is not None and getattr(mode, "value", mode) != "NextStep":
            raise ValueError(f"env's autoreset mode must be NEXT_STEP, got {mode}")
        self.env = env
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self):
        seeds = [s for s in self._seeds if s is not None]
        seed = [int(s) for s in self._seeds] if len(seeds) == self.num_envs else None
        obs, info = self.env.reset(seed=seed, options=self._options[0] or None)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = self._per_env(info, np.ones(self.num_envs, dtype=bool))
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, reward, terminated, truncated, info = self.env.step(self._actions)
        done = np.asarray(terminated) | np.asarray(truncated)
        infos = self._per_env(info, np.ones(self.num_envs, dtype=bool))
        if done.any():
            for i in np.flatnonzero(done):
                infos[i]["terminal_observation"] = {k: v[i].copy() for k, v in obs.items()}
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            obs, reset_info = self.env.reset(options={"reset_mask": done})
            for i, extra in enumerate(self._per_env(reset_info, done)):
                if done[i]:
                    self.reset_infos[i] = extra
        return obs, np.asarray(reward, dtype=np.float32), done, infos

    @staticmethod
    def _per_env(info: dict, rows: np.ndarray) -> list[dict]:
        """Gymnasium's batched info (arrays with ``_key`` masks) as one dict per sub-env."""
        out: list[dict] = [{} for _ in range(len(rows))]
        for key, value in info.items():
            if key.startswith("_"):
                continue
            mask = info.get(f"_{key}", rows)
            nested = SB3VecEnv._per_env(value, rows) if isinstance(value, dict) else None
            for i in np.flatnonzero(mask & rows):
                out[i][key] = value[i] if nested is None else nested[i]
        return out

    def close(self) -> None:
        self.env.close()

    # SB3's attribute plumbing: the sub-envs share one object, so attributes are the vector env's.
    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self.env.unwrapped, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self.env.unwrapped, attr_name, value)

    def env_method(
        self, method_name: str, *args, indices: VecEnvIndices = None, **kwargs
    ) -> list[Any]:
        method = getattr(self.env.unwrapped, method_name)
        return [method(*args, **kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]
