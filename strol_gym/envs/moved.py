"""Old module paths of the envs, kept importable for one release (0.2) after the move to
subpackages by simulator: importing one warns and gives the new module itself, so its names,
private ones included, and Minari headers or entry points that name the old path still resolve.
"""

from __future__ import annotations

import importlib
import sys
import warnings
from types import ModuleType

MOVED: dict[str, str] = {
    "strol_gym.envs.base": "strol_gym.envs.contract",
    "strol_gym.envs.vector_base": "strol_gym.envs.vector",
    "strol_gym.envs.panda_ik": "strol_gym.envs.panda.ik",
    "strol_gym.envs.panda_ik_batched": "strol_gym.envs.panda.ik_batched",
    "strol_gym.envs.robot_scene": "strol_gym.envs.robot.scene",
    "strol_gym.envs.robot_seeds": "strol_gym.envs.robot.seeds",
    "strol_gym.envs.vector_robot": "strol_gym.envs.robot.vector",
    "strol_gym.envs.vector_highway": "strol_gym.envs.highway.vector",
    "strol_gym.envs.study_participant": "strol_gym.envs.study.participant",
    "strol_gym.envs.study_user": "strol_gym.envs.study.user",
    "strol_gym.envs.study_scene": "strol_gym.envs.study.scene",
    "strol_gym.benchmarks.engine.study_authors": "strol_gym.envs.study.metrics",
}
"""Old module → new module. (``strol_gym.envs.panda``, ``.robot``, ``.highway`` and ``.study``
are now packages under the same names; ``strol_gym.envs.study`` resolves the old module's
other names itself, with a warning.)"""
_CONTROLLER = "strol_gym.envs.study.controller"
_GEOMETRY = "strol_gym.envs.study.geometry"
SPLIT: dict[str, dict[str, str]] = {
    "strol_gym.envs.study_v1": {
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
    },
}
"""Old module → {name: its new module}, for a module whose names went to several places."""


def alias(old: str) -> ModuleType:
    """Warn that ``old`` moved and put its new module in ``sys.modules`` under the old name."""
    new = MOVED[old]
    warnings.warn(
        f"{old} moved to {new}; the old path works until strol-gym 0.3",
        DeprecationWarning,
        stacklevel=3,
    )
    module = importlib.import_module(new)
    sys.modules[old] = module
    return module


def warn_split(old: str) -> object:
    """The ``__getattr__`` of an old module split across new ones (``SPLIT``): warns on import,
    then each name resolves (with a warning) from its new module."""
    warnings.warn(
        f"{old} was split (see strol_gym.envs.moved.SPLIT); the old path works until 0.3",
        DeprecationWarning,
        stacklevel=3,
    )
    return exports(old, {}, SPLIT[old])


def moved_name(package: str, names: dict[str, str], name: str) -> object:
    """A name that ``package`` (a module before it became a package) held and that now lives in
    ``names[name]``: warns and returns it; other names raise AttributeError as usual."""
    if name not in names:
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    warnings.warn(
        f"{package}.{name} moved to {names[name]}.{name}; the old path works until strol-gym 0.3",
        DeprecationWarning,
        stacklevel=3,
    )
    return getattr(importlib.import_module(names[name]), name)


def exports(package: str, public: dict[str, str], moved: dict[str, str] | None = None):
    """A package's module ``__getattr__``: ``public`` names (name → module) load their module
    on first use, so importing the package imports no simulator; ``moved`` names (the old
    module's other names, see :func:`moved_name`) warn."""
    moved = moved or {}

    def __getattr__(name: str) -> object:
        if name in public:
            return getattr(importlib.import_module(public[name]), name)
        return moved_name(package, moved, name)

    return __getattr__
