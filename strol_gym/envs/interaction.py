"""Former home of the shared env code; kept so that existing imports work.

Everything lives in :mod:`strol_gym.envs.base` now: ``CorrectionEnvMixin`` is
:class:`strol_gym.envs.base.CorrectionEnv`.
"""

from strol_gym.envs.base import RESET_OPTIONS, CorrectionEnv, int_arg, vector_arg
from strol_gym.humans import HumanFactory

CorrectionEnvMixin = CorrectionEnv

__all__ = ["RESET_OPTIONS", "CorrectionEnvMixin", "HumanFactory", "int_arg", "vector_arg"]
