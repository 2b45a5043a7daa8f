"""StROL-Highway-v0: two cars on highway-env's road, the human's car correcting the robot's.

``env`` (the single env on highway-env) and ``vector`` (N of them batched in numpy). Names
load their module on first use.
"""

from strol_gym.lazy import exports

_ENV = "strol_gym.envs.highway.env"
__all__ = ["ROAD_LENGTH", "HighwayEnv", "HumanVehicle", "VectorHighwayEnv"]
__getattr__ = exports(
    __name__,
    {
        "ROAD_LENGTH": _ENV,
        "HighwayEnv": _ENV,
        "HumanVehicle": _ENV,
        "VectorHighwayEnv": "strol_gym.envs.highway.vector",
    },
)
