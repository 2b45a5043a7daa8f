"""StROL-Robot-v0: a 7-DoF Panda hand moved by IK, corrected by a simulated human.

``env`` (the single env), ``vector`` (N of them batched), ``scene`` (the MuJoCo scene built
from a RobotTask) and ``seeds`` (the IK seed table). Names load their module on first use.
"""

from strol_gym.lazy import exports

__all__ = ["RobotEnv", "VectorRobotEnv"]
__getattr__ = exports(
    __name__,
    {"RobotEnv": "strol_gym.envs.robot.env", "VectorRobotEnv": "strol_gym.envs.robot.vector"},
)
