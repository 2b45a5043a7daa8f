"""Gymnasium envs, one subpackage per simulator, the contract they share at the root.

- ``contract``: :class:`CorrectionEnv`, what every env does with the human, θ̂, actions,
  observation and info; ``vector``: :class:`VectorCorrectionEnv`, N of one env batched.
- ``panda``: the Franka Panda arm (MuJoCo model, IK for one arm and for N).
- ``robot``: StROL-Robot-v0 (single and vector); ``highway``: StROL-Highway-v0 (single and
  vector); ``study``: StROL-Study-v0, -v1 and -v2 (the user study: scene, people who push,
  metrics).

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
