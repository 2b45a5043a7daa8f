"""Gymnasium envs: StROL-Robot-v0 (strol_gym.envs.robot) and StROL-Highway-v0 (.highway).

Modules are imported by ``gymnasium.make`` through the entry points in
strol_gym.registration, so importing this package loads neither MuJoCo nor highway-env.

MuJoCo picks its OpenGL backend when it is first imported, and every MuJoCo env module is
imported after this package: default to headless EGL here when there is no display (set
``MUJOCO_GL`` yourself to override, e.g. osmesa).
"""

import os

if "MUJOCO_GL" not in os.environ and not (
    os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
):
    os.environ["MUJOCO_GL"] = "egl"
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
