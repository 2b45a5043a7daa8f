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
    "stable-baselines3",
    "safetensors",
    "matplotlib",
)
NUMERIC_PACKAGES = ("numpy", "scipy", "torch", "gymnasium", "mujoco", "highway-env")
"""The packages whose version can change a record's bytes (their arithmetic, or the simulation
an env runs on them): within setup.cfg's ranges a result's means and verdicts hold, its bytes
only under the lock (docs/reproducibility.md), so a results folder is resumed only under the
versions it was made with."""


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


def version_changes(recorded: dict[str, Any], now: dict[str, Any] | None = None) -> list[str]:
    """``"torch 2.13.0 -> 2.14.1"`` for each of ``NUMERIC_PACKAGES`` whose version in ``now``
    (default: installed) differs from ``recorded``; a package the record lacks counts as
    changed, since nothing says it was the same."""
    now = package_versions() if now is None else now
    return [
        f"{name} {recorded.get(name, 'unrecorded')} -> {now.get(name)}"
        for name in NUMERIC_PACKAGES
        if recorded.get(name, "unrecorded") != now.get(name)
    ]


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
