"""The Robot env's scene: a Panda on a pedestal at a table with a plate and a cup (MJCF).

The template ``strol_gym/assets/robot_scene.xml`` is filled in at runtime from a ``RobotTask``
(its workspace box, plate and cup) around gymnasium-robotics' Panda files (``panda``).
"""

from __future__ import annotations

import importlib.resources

import mujoco
import numpy as np

from strol_gym.envs.panda.model import compile_model, fmt, franka_assets_dir, look_at
from strol_gym.tasks.robot import RobotTask

TABLE_TOP = 0.75
"""World height of the table top, i.e. of the task frame's origin (metres)."""
BASE_IN_TASK = np.array([0.05, -0.10, 0.10])
"""The Panda's base in the task frame: 10 cm behind the workspace's near face, centred on its
y range and on a 10 cm pedestal. Chosen (by a reachability search over base positions) so that
IK reaches every point of RobotTask's workspace box, the gripper pointing down (median tilt 3°
over a grid of the box, 90th percentile 8°, up to ~50° next to the base and at the far bottom
corners)."""


def scene_xml(task: RobotTask, offwidth: int = 640, offheight: int = 480) -> str:
    """The MJCF of the scene for ``task``, built at runtime around the Franka model files."""
    template = importlib.resources.files("strol_gym").joinpath("assets/robot_scene.xml")
    lift = np.array([0.0, 0.0, TABLE_TOP])
    low, high = task.workspace_low, task.workspace_high
    base = BASE_IN_TASK + lift
    table_lo = np.minimum(low, BASE_IN_TASK)[:2] - 0.15
    table_hi = high[:2] + 0.15
    center = 0.5 * (low + high) + lift
    eye = center + np.array([1.55, -1.05, 0.75])
    values = {
        "FRANKA": str(franka_assets_dir()),
        "OFFWIDTH": str(int(offwidth)),
        "OFFHEIGHT": str(int(offheight)),
        "CAM_POS": fmt(eye),
        "CAM_XYAXES": look_at(eye, center - np.array([0.0, 0.0, 0.12])),
        "TABLE_POS": fmt([*(0.5 * (table_lo + table_hi)), 0.5 * TABLE_TOP]),
        "TABLE_SIZE": fmt([*(0.5 * (table_hi - table_lo)), 0.5 * TABLE_TOP]),
        "PEDESTAL_POS": fmt(base - [0.0, 0.0, 0.5 * BASE_IN_TASK[2]]),
        "PEDESTAL_SIZE": fmt([0.09, max(0.5 * BASE_IN_TASK[2], 1e-3)]),
        "PLATE_POS": fmt(task.plate + lift + [0.0, 0.0, 0.005]),
        "CUP_POS": fmt([*task.cup[:2], TABLE_TOP + 0.5 * max(task.cup[2], 0.02)]),
        "CUP_SIZE": fmt([0.04, 0.5 * max(task.cup[2], 0.02)]),
        "BOX_POS": fmt(center),
        "BOX_SIZE": fmt(0.5 * (high - low)),
        "BASE_POS": fmt(base),
    }
    xml = template.read_text()
    for key, value in values.items():
        xml = xml.replace("{" + key + "}", value)
    return xml


def build_model(task: RobotTask, offwidth: int = 640, offheight: int = 480) -> mujoco.MjModel:
    """The compiled scene. Cached per process: envs never modify their model."""
    return compile_model(scene_xml(task, offwidth, offheight))
