"""Deprecated: moved to strol_gym.envs.study.participant; the old name goes in the next release."""

from strol_gym.envs.moved import alias

alias(__name__, "strol_gym.envs.study.participant")
