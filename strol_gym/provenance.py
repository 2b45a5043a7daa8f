"""Where a result came from: the versions of the packages that made it and the git revision.

Shared by the benchmark's results folders, the session logs of ``strol_gym.wrappers`` and the
sidecars of trained ĝ weights (``strol_gym.learners.checkpoint``).
"""

from __future__ import annotations

import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

PACKAGES = (
    "strol-gym",
    "numpy",
    "scipy",
    "torch",
    "gymnasium",
    "mujoco",
    "highway-env",
    "gymnasium-robotics",
    "matplotlib",
)


def package_versions() -> dict[str, str | None]:
    """The installed version of each package a result depends on (None: not installed), and the
    Python version: the one list that results folders, session logs and ĝ sidecars record."""
    out: dict[str, str | None] = {}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    out["python"] = platform.python_version()
    return out


def git_revision() -> dict[str, Any] | None:
    """HEAD of the repository this package runs from, and whether the tree had edits."""
    here = Path(__file__).resolve().parent
    try:
        rev = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=10
        )
        if rev.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=10,
        )
        return {"commit": rev.stdout.strip(), "dirty": bool(dirty.stdout.strip())}
    except (OSError, subprocess.SubprocessError):
        return None
