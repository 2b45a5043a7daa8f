"""VectorOnlineLearningWrapper: an online reward learner for every sub-env of a vector env."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import VectorEnv, VectorWrapper

from strol_gym.learners.protocol import OnlineRewardLearner
from strol_gym.learners.registry import make_learner
from strol_gym.metrics import cos_error, error
from strol_gym.tasks.base import Task
from strol_gym.wrappers.online_learning import LearningEnv, episode_regret, theta_space

FIXED_STATE = frozenset({"name", "task_id", "config", "arch", "model"})
"""``state_dict`` keys that do not change as a learner learns (its configuration, ĝ's weights)."""


def _rows(metric: Any, theta_star: np.ndarray, theta_hat: np.ndarray) -> np.ndarray:
    """A metric of ``strol_gym.metrics`` for each row (the single wrapper's definition)."""
    return np.array([metric(s, h) for s, h in zip(theta_star, theta_hat, strict=True)])


class VectorOnlineLearningWrapper(VectorWrapper):
    """``OnlineLearningWrapper`` for a strol-gym vector env: sub-env i gets its own learner.

    The learners are one learner object working on a batch (every strol-gym learner takes a
    leading batch axis), row i being sub-env i's. When the sub-envs that correct at a step are
    only some of them (episodes out of step after a termination), a learner whose state is θ̂
    alone (Gradient, One, MOF, StROL, e2e: ``state_dict`` holds nothing else that changes)
    updates just those rows; a learner with more state (a particle filter, running statistics)
    needs the sub-envs in step (all correcting and resetting together, as the Robot env's
    fixed-length episodes do) and raises otherwise. Everything else is the single wrapper's:
    θ̂ goes to the env (``set_theta_hat``), into ``obs["theta_hat"]`` and ``info["theta_hat"]``;
    at an episode's end, info holds ``error``, ``cos_error`` and (unless ``regret=False``)
    ``regret`` for the sub-envs that ended, with their ``_key`` masks. Autoreset must be
    ``NEXT_STEP`` (strol-gym's vector envs and gymnasium's ``SyncVectorEnv``).
    """

    def __init__(
        self,
        env: VectorEnv,
        learner: str | OnlineRewardLearner,
        learner_kwargs: dict[str, Any] | None = None,
        replace_reward: bool = False,
        regret: bool = True,
    ) -> None:
        super().__init__(env)
        base = env.unwrapped
        if not isinstance(base, LearningEnv):  # it has .task and .set_theta_hat
            raise ValueError(
                "env must be a strol-gym vector env (env.unwrapped needs .task and "
                f".set_theta_hat), got {type(base).__name__}"
            )
        mode = env.metadata.get("autoreset_mode")
        if mode is not None and getattr(mode, "value", mode) != "NextStep":
            raise ValueError(f"env's autoreset mode must be NEXT_STEP, got {mode}")
        self.learner = make_learner(learner, task=base.task, **(learner_kwargs or {}))
        self.rows_separable = set(self.learner.state_dict()) - FIXED_STATE == {"theta"}
        self.replace_reward = bool(replace_reward)
        self.score_regret = bool(regret)
        n = self.num_envs
        self.theta = np.zeros((n, base.task.dim))
        self._x = np.zeros((n, base.task.state_dim))
        self._x0 = np.zeros_like(self._x)
        self._done = np.zeros(n, dtype=bool)
        self._started = False
        self._base: LearningEnv = base
        self._theta_dtype = theta_space(self.single_observation_space).dtype

    @property
    def task(self) -> Task:
        return self._base.task

    # ------------------------------------------------------------------ the learners
    def _reset_learners(self, rows: np.ndarray, info: dict) -> None:
        theta0 = info.get("theta_hat0")
        if theta0 is None:
            start = np.tile(self.learner.reset(None), (len(rows), 1))
        else:
            start = np.asarray(theta0, dtype=np.float64)[rows]
        if len(rows) == self.num_envs:
            self.theta = np.array(self.learner.reset(start), dtype=np.float64)
        elif self.rows_separable:
            self.theta[rows] = start
        else:
            raise ValueError(
                f"learner {type(self.learner).__name__} keeps more state than θ̂, so its "
                "sub-envs must reset together; these reset apart (use a learner whose state is "
                "θ̂ alone, or sub-envs whose episodes stay in step)"
            )

    def _update(self, rows: np.ndarray, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> None:
        if len(rows) == self.num_envs:
            if self.rows_separable:  # a subset's update may have left a subset's θ̂ there
                self.learner.theta = self.theta.copy()
            self.theta = np.array(self.learner.update(x, u_h, u_r), dtype=np.float64)
        elif self.rows_separable:
            self.learner.theta = self.theta[rows].copy()
            self.theta[rows] = self.learner.update(x, u_h, u_r)
        else:
            raise ValueError(
                f"learner {type(self.learner).__name__} keeps more state than θ̂, so its "
                "sub-envs must correct together; only some corrected at this step"
            )

    def _publish(self, obs: dict, info: dict) -> None:
        self._base.set_theta_hat(self.theta)
        obs["theta_hat"] = self.theta.astype(self._theta_dtype)
        info["theta_hat"] = self.theta.copy()
        info["_theta_hat"] = np.ones(self.num_envs, dtype=bool)

    # ------------------------------------------------------------------ reset / step
    def reset(self, *, seed: Any = None, options: dict[str, Any] | None = None):
        mask = (options or {}).get("reset_mask")
        rows = np.arange(self.num_envs) if mask is None else np.flatnonzero(mask)
        obs, info = self.env.reset(seed=seed, options=options)
        obs, info = dict(obs), dict(info)
        self._reset_learners(rows, info)
        self._publish(obs, info)
        state = np.asarray(obs["state"], dtype=np.float64)
        self._x[rows] = state[rows]
        self._x0[rows] = state[rows]
        self._done[rows] = False
        self._started = True
        return obs, info

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        obs, reward, terminated, truncated, info = self.env.step(actions)
        obs, info = dict(obs), dict(info)
        reward = np.array(reward, dtype=np.float64)
        again = np.flatnonzero(self._done)  # the sub-envs this step reset (NEXT_STEP)
        state = np.asarray(obs["state"], dtype=np.float64)
        if len(again):
            self._reset_learners(again, {k: v for k, v in info.items() if k == "theta_hat0"})
            self._x0[again] = state[again]
        corr = np.asarray(info.get("is_correction", np.zeros(self.num_envs)), dtype=bool)
        corr[again] = False
        rows = np.flatnonzero(corr)
        if len(rows):
            x = info.get("correction_state")
            x = self._x[rows] if x is None else np.asarray(x, dtype=np.float64)[rows]
            u_h = np.asarray(obs["correction"], dtype=np.float64)[rows]
            u_r = np.asarray(info["robot_action"], dtype=np.float64)[rows]
            self._update(rows, x, u_h, u_r)
        self._publish(obs, info)
        stepped = ~self._done  # the sub-envs that reset at this step report their reset
        if self.replace_reward and stepped.any():
            info["true_reward"], info["_true_reward"] = np.where(stepped, reward, 0.0), stepped
            phi = np.asarray(info["phi"], dtype=np.float64)
            reward = np.array([np.dot(t, p) for t, p in zip(self.theta, phi, strict=True)])
            reward[again] = 0.0
        ended = np.asarray(terminated) | np.asarray(truncated)
        end = np.flatnonzero(ended)
        if len(end):
            theta_star = np.asarray(info["theta_star"], dtype=np.float64)[end]
            theta_hat = self.theta[end]
            scores = {
                "error": _rows(error, theta_star, theta_hat),
                "cos_error": _rows(cos_error, theta_star, theta_hat),
            }
            if self.score_regret:
                scores["regret"] = np.array(
                    episode_regret(self.task, theta_hat, theta_star, self._x0[end])
                )
            for key, value in scores.items():
                info[key] = np.zeros(self.num_envs)
                info[key][end] = value
                info[f"_{key}"] = ended.copy()
        self._done = ended
        self._x = state.copy()
        return obs, reward, terminated, truncated, info
