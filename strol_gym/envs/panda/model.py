"""The Franka Panda from gymnasium-robotics' shipped model files, for any strol-gym MuJoCo env.

Where the files are, the arm's constants (joint count, home pose, end-effector site), compiling
a scene that includes them (cached, gravity-compensated) and the small MJCF formatting helpers
scene builders share. The Robot env's table scene (``robot_scene``) and the user-study env
build on it.
"""

from __future__ import annotations

import functools
import importlib.util
import os
import threading
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

Q_HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 0.0, 0.785])
"""Gripper down: joint 6 of this model is offset by −π/2 from the real Panda's."""
N_ARM = 7
"""Arm joints; they come first in ``qpos`` (the two finger joints follow)."""
FINGER_OPEN = 0.04
EE_SITE = "end_effector"
ARM_BODIES = tuple(f"panda0_link{i}" for i in range(8))
"""The arm's bodies (link0 is the base), named as in the model files' chain.xml."""


def has_display() -> bool:
    """Whether an on-screen window can open (a viewer without one would abort the process)."""
    return os.name != "posix" or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )


def franka_assets_dir() -> Path:
    """gymnasium-robotics' shipped Franka Panda model files (Apache-2.0)."""
    spec = importlib.util.find_spec("gymnasium_robotics")
    if spec is None or spec.origin is None:
        raise ImportError(
            "strol-gym's MuJoCo envs need gymnasium-robotics (pip install gymnasium-robotics)"
        )
    path = Path(spec.origin).parent / "envs" / "assets" / "kitchen_franka" / "franka_assets"
    if not (path / "chain.xml").exists():
        raise FileNotFoundError(f"Franka Panda model files not found in {path}")
    return path


def fmt(v: Any) -> str:
    """Numbers as an MJCF attribute value ("x y z")."""
    return " ".join(f"{float(a):.6g}" for a in np.atleast_1d(v))


def look_at(eye: np.ndarray, target: np.ndarray) -> str:
    """MuJoCo camera xyaxes for a camera at ``eye`` looking at ``target`` (z up)."""
    f = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(f, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return fmt(np.concatenate([x, np.cross(x, f)]))


@functools.lru_cache(maxsize=8)
def compile_model(xml: str) -> mujoco.MjModel:
    """Compile an MJCF that includes the Panda; cached per process, so never modify the result.

    The arm bodies get gravity compensation, so ``mj_step`` (if a user calls it) holds the arm
    up; reflections are off (they cost ~8x frame rate and add nothing here).
    """
    return prepare_model(mujoco.MjModel.from_xml_string(xml))


def prepare_model(model: mujoco.MjModel) -> mujoco.MjModel:
    """Gravity-compensate the arm bodies and turn reflections off (in place; returns it)."""
    arm = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) for name in ARM_BODIES]
    model.body_gravcomp[arm] = 1.0
    model.mat_reflectance[:] = 0.0
    return model


class PassiveViewer:
    """``mujoco.viewer.launch_passive``'s handle whose ``close`` also waits for the viewer's
    thread: exiting while it still renders makes GLFW's exit handler crash the process (a
    segfault at interpreter exit, seen under Xvfb). Keyword arguments go to
    ``launch_passive``; the handle is ``.handle``. Needs a display (see ``has_display``)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, **kwargs: Any) -> None:
        from mujoco import viewer

        before = set(threading.enumerate())
        self.handle = viewer.launch_passive(model, data, **kwargs)
        self.threads = [t for t in threading.enumerate() if t not in before]

    def sync(self) -> None:
        self.handle.sync()

    def is_running(self) -> bool:
        return self.handle.is_running()

    def close(self, timeout: float = 10.0) -> None:
        self.handle.close()
        for t in self.threads:
            t.join(timeout=timeout)


class MujocoRendering:
    """``render`` and ``close`` of a strol-gym MuJoCo env (a mixin placed first): offscreen
    frames of the scene's ``overview`` camera for ``render_mode="rgb_array"`` (shadows and
    reflections off, ~8x the frame rate), MuJoCo's passive viewer for ``"human"``."""

    model: mujoco.MjModel
    data: mujoco.MjData
    render_mode: str | None
    width: int
    height: int
    _renderer: mujoco.Renderer | None = None
    _viewer: Any = None

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            import gymnasium as gym

            gym.logger.warn(
                "render() called without a render_mode; "
                'make the env with render_mode="rgb_array" or "human"'
            )
            return None
        mujoco.mj_forward(self.model, self.data)
        if self.render_mode == "rgb_array":
            if self._renderer is None:
                self._renderer = mujoco.Renderer(self.model, self.height, self.width)
                flags = self._renderer.scene.flags
                flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
                flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
            self._renderer.update_scene(self.data, camera="overview")
            return self._renderer.render()
        if self._viewer is None:
            if not has_display():
                # GLFW would abort the whole process; fail politely instead.
                raise RuntimeError(
                    'render_mode="human" needs a display (DISPLAY is not set): run under '
                    'xvfb-run, or use render_mode="rgb_array" for headless frames'
                )
            self._viewer = PassiveViewer(self.model, self.data)
        self._viewer.sync()
        return None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        super().close()  # type: ignore[misc]
