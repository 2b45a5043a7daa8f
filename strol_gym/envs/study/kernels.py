"""The study controller's per-physics-step speed checks as compiled loops (numba, through
``strol_gym.compiled``): v2's joint brake reads them after every physics step, where a Python
generator over seven joints cost a fifth of the step's own physics.

The same IEEE operations as the plain path's, in the same order, without fast-math
(tests/test_compiled.py, and the study's golden rollouts on both paths)."""

from __future__ import annotations

import numpy as np

from strol_gym.compiled import compiled


@compiled
def above(speed: np.ndarray, cap: np.ndarray) -> bool:
    """Whether any |speed_j| > cap_j."""
    for j in range(cap.shape[0]):
        if abs(speed[j]) > cap[j]:
            return True
    return False


@compiled
def ahead_above(
    speed: np.ndarray, acc: np.ndarray, extra: np.ndarray, h: float, cap: np.ndarray
) -> bool:
    """Whether any joint's speed ``h`` seconds on, |speed_j + h (acc_j + extra_j)|, passes
    cap_j (``ImpedanceController._ahead``'s look-ahead, its M⁻¹ Δτ term ``extra``)."""
    for j in range(cap.shape[0]):
        if abs(speed[j] + h * (acc[j] + extra[j])) > cap[j]:
            return True
    return False


@compiled
def drift_above(speed: np.ndarray, acc: np.ndarray, h: float, cap: np.ndarray) -> bool:
    """Whether any |speed_j + h acc_j| > cap_j: the look-ahead under the last step's torques."""
    for j in range(cap.shape[0]):
        if abs(speed[j] + h * acc[j]) > cap[j]:
            return True
    return False


__all__ = ["above", "ahead_above", "drift_above"]
