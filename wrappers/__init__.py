"""Gymnasium wrappers that apply an online reward learner to a strol-gym env."""

from strol_gym.wrappers.online_learning import OnlineLearningWrapper
from strol_gym.wrappers.vector_online_learning import VectorOnlineLearningWrapper

__all__ = ["OnlineLearningWrapper", "VectorOnlineLearningWrapper"]
