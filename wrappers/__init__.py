"""Gymnasium wrappers that apply an online reward learner to a strol-gym env."""

from strol_gym.wrappers.online_learning import OnlineLearningWrapper

__all__ = ["OnlineLearningWrapper"]
