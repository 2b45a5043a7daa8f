"""Shared test setup: headless rendering backends, set before any test imports a renderer."""

from __future__ import annotations

import os

# MuJoCo picks its OpenGL backend at import; EGL renders without a display.
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
