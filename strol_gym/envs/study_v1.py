"""Deprecated: split into strol_gym.envs.study (env, versions, controller, geometry); this
path works until 0.3."""

from strol_gym.envs.moved import warn_split

__getattr__ = warn_split(__name__)
