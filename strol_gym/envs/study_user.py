"""Deprecated: moved (see strol_gym.envs.moved.MOVED); this path works until 0.3."""

from strol_gym.envs.moved import alias

alias(__name__)
