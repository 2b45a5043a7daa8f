"""OnlineLearningWrapper: applies an online reward learner to a strol-gym env."""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np
from gymnasium.vector import VectorEnv

from strol_gym.learners.protocol import OnlineRewardLearner
from strol_gym.learners.registry import make_learner
from strol_gym.metrics import cos_error, episode_regret, error
from strol_gym.tasks.base import Task


@runtime_checkable
class LearningEnv(Protocol):
    """What the learning wrappers need of a strol-gym env, single or vector (its ``unwrapped``):
    its Task, and a way to hand it θ̂ (a teacher human corrects relative to it)."""

    @property
    def task(self) -> Task: ...

    @property
    def theta_hat(self) -> np.ndarray: ...

    def set_theta_hat(self, theta: np.ndarray) -> None: ...


def learning_env(env: gym.Env | VectorEnv) -> LearningEnv:
    """``env.unwrapped`` as a strol-gym env (single or vector): its Task and θ̂, else
    ValueError. Typed access for code that holds what ``gym.make`` returned."""
    base = env.unwrapped
    if not isinstance(base, LearningEnv):  # it has .task, .theta_hat and .set_theta_hat
        raise ValueError(
            "env must be a strol-gym env (env.unwrapped needs .task and .set_theta_hat), "
            f"got {type(base).__name__}"
        )
    return base


__all__ = ["LearningEnv", "OnlineLearningWrapper", "cos_error", "episode_regret", "learning_env"]


def theta_space(space: gym.Space) -> gym.spaces.Box:
    """The ``theta_hat`` Box of a strol-gym env's Dict observation space (where the learning
    wrappers publish θ̂), else ValueError."""
    box = space.spaces.get("theta_hat") if isinstance(space, gym.spaces.Dict) else None
    if not isinstance(box, gym.spaces.Box):
        raise ValueError(f"env's observations must be a Dict with a 'theta_hat' Box, got {space}")
    return box


class OnlineLearningWrapper(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Let a learner update θ̂ from the human's corrections as the episode runs.

    Each step, when ``info["is_correction"]`` is true, the learner sees x, u_H (this
    observation's ``"correction"``) and u_R (``info["robot_action"]``) and returns θ̂. x is
    ``info["correction_state"]`` when the env provides it (a correction that spans several
    steps, learned from the state where it began), else the previous observation's ``"state"``.
    The wrapper hands θ̂ to the env with ``env.unwrapped.set_theta_hat`` (so the human's next
    correction and the env's observation use it) and writes it into ``obs["theta_hat"]`` and
    ``info["theta_hat"]``. The observation space does not change.

    Args:
        env: a strol-gym env (``env.unwrapped.task`` is its Task).
        learner: a learner object, a registered name (``strol_gym.list_learners()``), a
            ``"module:attr"`` naming a learner factory or class, or a factory; names are built
            with ``make_learner(learner, task=env.unwrapped.task, **learner_kwargs)``.
        learner_kwargs: keyword arguments for ``make_learner`` when ``learner`` is a name.
        replace_reward: if true, the reward becomes θ̂·φ(x') with the updated θ̂ (the robot's
            own belief), and ``info["true_reward"]`` keeps the env's R(x', θ*).
        regret: if false, the last step's ``info`` has no ``"regret"``: for a runner that scores
            many episodes at once with one batched ``task.regret`` call (planning is most of
            the cost of scoring an episode).

    The learner starts each episode from the prior modes' mean, or from ``info["theta_hat0"]``
    when the env's reset provides one.

    At the end of an episode (terminated or truncated) ``info`` also holds ``"error"`` =
    ‖θ* − θ̂‖, ``"cos_error"`` = 1 − cos(θ*, θ̂) (1.0 when θ̂ = 0) and ``"regret"`` =
    ``task.regret(θ̂, θ*, x0)`` from the episode's start state x0 (NaN when the task has no
    planner; absent with ``regret=False``).
    """

    def __init__(
        self,
        env: gym.Env,
        learner: str | OnlineRewardLearner,
        learner_kwargs: dict[str, Any] | None = None,
        replace_reward: bool = False,
        regret: bool = True,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self,
            learner=learner,
            learner_kwargs=learner_kwargs,
            replace_reward=replace_reward,
            regret=regret,
        )
        gym.Wrapper.__init__(self, env)
        base = learning_env(env)
        for name, flag in (("replace_reward", replace_reward), ("regret", regret)):
            if not isinstance(flag, bool | np.bool_):  # "no" would be true: refuse, not guess
                raise ValueError(f"{name} must be True or False, got {flag!r}")
        if learner_kwargs is not None and not isinstance(learner_kwargs, dict):
            raise ValueError(f"learner_kwargs must be a dict, got {learner_kwargs!r}")
        self.learner = make_learner(learner, task=base.task, **(learner_kwargs or {}))
        self.replace_reward = bool(replace_reward)
        self.score_regret = bool(regret)
        self._x: np.ndarray | None = None
        self._x0: np.ndarray | None = None
        self._base: LearningEnv = base
        self._theta_dtype = theta_space(self.observation_space).dtype

    @property
    def task(self) -> Task:
        return self._base.task

    def _publish(self, obs: dict, info: dict) -> None:
        theta = np.asarray(self.learner.theta, dtype=np.float64)
        self._base.set_theta_hat(theta)
        obs["theta_hat"] = theta.astype(self._theta_dtype)
        info["theta_hat"] = theta.copy()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        obs, info = dict(obs), dict(info)
        # An env that draws θ̂0 itself (the study env: U[−1, 1]^d) says so in "theta_hat0".
        theta0 = info.get("theta_hat0")
        self.learner.reset(None if theta0 is None else np.asarray(theta0, dtype=np.float64))
        self._publish(obs, info)
        self._x = np.asarray(obs["state"], dtype=np.float64).copy()
        self._x0 = self._x.copy()
        return obs, info

    def step(self, action):
        if self._x is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        obs, reward, terminated, truncated, info = self.env.step(action)
        obs, info = dict(obs), dict(info)
        if info.get("is_correction", False):
            x = info.get("correction_state")
            self.learner.update(
                self._x if x is None else np.asarray(x, dtype=np.float64),
                np.asarray(obs["correction"], dtype=np.float64),
                np.asarray(info["robot_action"], dtype=np.float64),
            )
        self._publish(obs, info)
        theta_hat = info["theta_hat"]
        if self.replace_reward:
            info["true_reward"] = reward
            reward = float(np.dot(theta_hat, np.asarray(info["phi"], dtype=np.float64)))
        if terminated or truncated:
            theta_star = np.asarray(info["theta_star"], dtype=np.float64)
            info["error"] = error(theta_star, theta_hat)
            info["cos_error"] = cos_error(theta_star, theta_hat)
            if self.score_regret:
                info["regret"] = episode_regret(self.task, theta_hat, theta_star, self._x0)[0]
        self._x = np.asarray(obs["state"], dtype=np.float64).copy()
        return obs, reward, terminated, truncated, info
