"""Deprecated: moved to strol_gym.envs.highway.vector; the old name goes in the next release."""

from strol_gym.envs.moved import alias

alias(__name__, "strol_gym.envs.highway.vector")
