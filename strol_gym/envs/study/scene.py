"""The user study's scene: a Panda holding a cup on a table with a pitcher and a plate.

World frame = the robot base frame = the study Tasks' frame (the base stands on the table top,
z = 0). gymnasium-robotics' Panda files are included unchanged; the cup is added to the hand
(link 7) with ``mujoco.MjSpec``, so it moves rigidly with the hand and the hand's contacts with
its own fingers stay filtered. Collisions: the arm, the cup, the pitcher and the plate (and its
riser) collide; the table collides with the cup only (the arm's base stands on it).

The arm's seven position servos become torque motors (gain 1, no bias, the Panda's torque limits
as their control range): the env's impedance controller writes joint torques to ``ctrl``.
"""

from __future__ import annotations

import functools

import mujoco
import numpy as np

from strol_gym.envs.panda.model import N_ARM, fmt, franka_assets_dir, look_at, prepare_model
from strol_gym.tasks.study import PITCHER, PLATE

CUP_RADIUS = 0.04
CUP_HALF_HEIGHT = 0.05
CUP_IN_HAND = np.array([0.0, 0.0, 0.26])
"""The cup's centre in link 7's frame: its rim at the end-effector site, between the fingers."""
PITCHER_RADIUS = 0.07
PITCHER_HEIGHT = 0.24
PLATE_RADIUS = 0.10
TIMESTEP = 0.005
"""Physics step (s): 10 per 0.05 s control step. The implicit-fast integrator keeps the compliant
arm stable at this step (the model files' 2 ms would cost 2.5x the physics per simulated
second; docs/study.md)."""
HOLD = 5
"""Physics steps per impedance update (the torque is held in between): 5 steps of 5 ms = 25 ms,
i.e. 40 Hz impedance control."""
JOINT_DAMPING = np.array([5.0, 5.0, 5.0, 5.0, 1.0, 1.0, 1.0])
"""Viscous joint damping (N m s/rad), integrated implicitly by MuJoCo (the model files' 100 on
the big joints makes the arm lag its setpoint by ~10 cm at 0.1 m/s)."""
ARMATURE = np.array([0.1, 0.1, 0.1, 0.1, 0.05, 0.05, 0.05])
"""Rotor inertia (kg m²): keeps the light wrist joints stable under held torques."""


def model_q(home_q: np.ndarray) -> np.ndarray:
    """The paper's (real Panda) joint angles in this model's convention (joint 6 − π/2)."""
    q = np.array(home_q, dtype=np.float64)
    q[5] -= np.pi / 2
    return q


def scene_xml(offwidth: int = 640, offheight: int = 480) -> str:
    franka = franka_assets_dir()
    eye = np.array([1.95, -1.45, 1.25])
    center = np.array([0.4, 0.05, 0.3])
    pitcher_pos = [*PITCHER[:2], PITCHER[2] + PITCHER_HEIGHT / 2]
    riser_h = max(PLATE[2] - 0.005, 0.0)
    return f"""<mujoco model="strol_study">
  <include file="{franka}/assets.xml"/>
  <include file="{franka}/actuator.xml"/>
  <compiler angle="radian" meshdir="{franka}/meshes"/>
  <visual>
    <global offwidth="{int(offwidth)}" offheight="{int(offheight)}"/>
    <headlight diffuse="0.6 0.6 0.6" ambient="0.3 0.3 0.3"/>
  </visual>
  <asset>
    <material name="table" rgba="0.62 0.48 0.34 1"/>
    <material name="plate" rgba="0.95 0.95 0.92 1"/>
    <material name="pitcher" rgba="0.35 0.55 0.85 0.9"/>
    <material name="cup" rgba="0.85 0.22 0.15 1"/>
  </asset>
  <worldbody>
    <light pos="0.5 0 2.5" dir="0 0 -1" diffuse="0.7 0.7 0.7"/>
    <camera name="overview" mode="fixed" pos="{fmt(eye)}" xyaxes="{look_at(eye, center)}"
            fovy="45"/>
    <geom name="table" type="box" pos="0.35 0 -0.025" size="0.75 0.9 0.025" material="table"
          contype="2" conaffinity="2"/>
    <geom name="pitcher" type="cylinder" pos="{fmt(pitcher_pos)}"
          size="{PITCHER_RADIUS} {PITCHER_HEIGHT / 2}" material="pitcher"
          contype="1" conaffinity="1"/>
    <geom name="riser" type="box" pos="{fmt([*PLATE[:2], riser_h / 2])}"
          size="0.08 0.08 {max(riser_h / 2, 1e-3)}" rgba="0.3 0.3 0.32 1"
          contype="1" conaffinity="1"/>
    <geom name="plate" type="cylinder" pos="{fmt(PLATE)}" size="{PLATE_RADIUS} 0.005"
          material="plate" contype="1" conaffinity="1"/>
    <body name="panda_base" pos="0 0 0">
      <include file="{franka}/chain.xml"/>
    </body>
  </worldbody>
</mujoco>"""


@functools.lru_cache(maxsize=4)
def build_model(offwidth: int = 640, offheight: int = 480) -> mujoco.MjModel:
    """The compiled scene (cached per process: envs never modify it)."""
    spec = mujoco.MjSpec.from_string(scene_xml(offwidth, offheight))
    hand = spec.body("panda0_link7")
    # The cup hangs from the hand, its axis opposite the gripper's approach axis: upright when
    # the gripper points down.
    flip = [0.0, 1.0, 0.0, 0.0]
    cup = hand.add_geom(
        name="cup",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[CUP_RADIUS, CUP_HALF_HEIGHT, 0.0],
        pos=CUP_IN_HAND,
        quat=flip,
        mass=0.2,
        material="cup",
    )
    cup.contype, cup.conaffinity = 3, 3
    hand.add_site(name="cup", pos=CUP_IN_HAND, quat=flip, size=[0.01, 0.0, 0.0])
    for body in spec.bodies[1:]:
        body.gravcomp = 1.0  # in the spec: MuJoCo skips gravcomp if none is set at compile
    model = prepare_model(spec.compile())
    model.opt.timestep = TIMESTEP
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    model.dof_damping[:N_ARM] = JOINT_DAMPING
    model.dof_armature[:N_ARM] = ARMATURE
    # Arm actuators: position servos -> torque motors within the Panda's torque limits.
    model.actuator_gainprm[:N_ARM] = 0.0
    model.actuator_gainprm[:N_ARM, 0] = 1.0
    model.actuator_biasprm[:N_ARM] = 0.0
    model.actuator_ctrlrange[:N_ARM] = model.actuator_forcerange[:N_ARM]
    return model
