"""Gymnasium wrappers that apply an online reward learner to a strol-gym env; ``sb3`` (imported
when asked for: it needs stable-baselines3) adapts a vector env to SB3's ``VecEnv``."""

from strol_gym.wrappers.online_learning import OnlineLearningWrapper
from strol_gym.wrappers.vector_online_learning import VectorOnlineLearningWrapper

__all__ = ["OnlineLearningWrapper", "VectorOnlineLearningWrapper"]
