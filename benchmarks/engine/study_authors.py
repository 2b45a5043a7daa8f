"""Deprecated: moved to strol_gym.envs.study.metrics; this path works until 0.3."""

from strol_gym.envs.moved import alias

alias(__name__)
