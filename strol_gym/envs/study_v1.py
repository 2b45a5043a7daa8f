"""Deprecated: split across strol_gym.envs.study (env, versions, controller, geometry); the old
name goes in the next release."""

from strol_gym.envs.moved import warn_split

_CONTROLLER = "strol_gym.envs.study.controller"
_GEOMETRY = "strol_gym.envs.study.geometry"
NAMES: dict[str, str] = {
    "StudyEnvV1": "strol_gym.envs.study.env",
    **dict.fromkeys(("PARTICIPANTS", "REST_TRUST"), "strol_gym.envs.study.versions"),
    **dict.fromkeys(
        ("VELOCITY_LIMIT", "TORQUE_LIMIT", "K_INTEGRAL", "INTEGRAL_MAX", "K_NULL", "D_NULL"),
        _CONTROLLER,
    ),
    **dict.fromkeys(("MODEL_EVERY", "LAMBDA_REG"), _CONTROLLER),
    **dict.fromkeys(
        ("REACH_LOW", "REACH_HIGH", "REACH_ANGLE", "SHOULDER", "REACH_RADIUS"), _GEOMETRY
    ),
    **dict.fromkeys(("PITCHER_CLEAR", "within_reach"), _GEOMETRY),
}
"""Each name the old module held → its new module."""

__getattr__ = warn_split(__name__, NAMES)
