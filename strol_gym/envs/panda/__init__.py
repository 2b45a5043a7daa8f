"""The Franka Panda arm in MuJoCo, shared by the Robot and Study envs: its model and scene
helpers (``model``) and its inverse kinematics, one arm (``ik``) and N arms batched
(``ik_batched``). Names load their module on first use."""

from strol_gym.lazy import exports

_MODEL = "strol_gym.envs.panda.model"
__all__ = [
    "ARM_BODIES",
    "EE_SITE",
    "FINGER_OPEN",
    "N_ARM",
    "Q_HOME",
    "BatchedPandaIK",
    "MujocoRendering",
    "PandaIK",
    "PassiveViewer",
    "compile_model",
    "fmt",
    "franka_assets_dir",
    "has_display",
    "look_at",
    "prepare_model",
]  # fmt: skip
__getattr__ = exports(
    __name__,
    {
        **dict.fromkeys(__all__, _MODEL),
        "PandaIK": "strol_gym.envs.panda.ik",
        "BatchedPandaIK": "strol_gym.envs.panda.ik_batched",
    },
)
