"""StROL-Study-v0 and -v1: the paper's user study, a person pushing a compliant Panda arm
that carries a cup, in MuJoCo.

``v0`` (as published, frozen) and ``v1`` (the env by version), ``scene`` (the MuJoCo scene),
``participant`` and ``user`` (simulated people who push), ``metrics`` (the study's metrics,
the authors' way included). Names load their module on first use.
"""

from strol_gym.envs.moved import exports

_V0 = "strol_gym.envs.study.v0"
__all__ = ["StudyEnv", "StudyEnvV1"]
__getattr__ = exports(
    __name__,
    {"StudyEnv": _V0, "StudyEnvV1": "strol_gym.envs.study.v1"},
    # what strol_gym.envs.study (one module until 0.2) also held
    dict.fromkeys(("HOLD", "END_HOLD", "TORQUE_LEVER", "Velocity"), _V0),
)
