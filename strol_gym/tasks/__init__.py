"""Settings (Tasks): φ, g, prior, action bound, start distribution and planner."""

from strol_gym.tasks.base import Task
from strol_gym.tasks.highway import HighwayTask
from strol_gym.tasks.robot import RobotTask

__all__ = ["HighwayTask", "RobotTask", "Task"]
