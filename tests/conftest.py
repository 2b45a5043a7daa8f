"""Shared test setup: headless rendering backends, set before any test imports a renderer."""

from __future__ import annotations

import os

# MuJoCo picks its OpenGL backend at import; EGL renders without a display.
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
# Reports' bootstrap intervals: 200 resamples in tests (the benchmark's default is 2,000);
# set here so the strol-bench subprocesses that tests start inherit it.
os.environ.setdefault("STROL_BOOTSTRAP_RESAMPLES", "200")

import pytest


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_a_temporary_folder(tmp_path_factory: pytest.TempPathFactory) -> None:
    """stable-baselines3 makes a log folder for every ``learn`` given none (``/tmp/SB3-<date>``
    by default); the tests' go under pytest's own temporary folder, which pytest prunes."""
    os.environ.setdefault("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3-logs")))
