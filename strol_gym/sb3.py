"""Moved: the SB3 adapter is ``strol_gym.wrappers.sb3.SB3VecEnv``. The old path warns when
used and goes in the next release (CHANGELOG.md)."""

from strol_gym.deprecation import moved

__getattr__ = moved(__name__, {"SB3VecEnv": "strol_gym.wrappers.sb3:SB3VecEnv"})
