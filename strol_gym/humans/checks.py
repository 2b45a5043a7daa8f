"""Checks of the numbers every human model takes: noise and bias in units of a_max, and β."""

from __future__ import annotations

from typing import Any

import numpy as np

MAX_FRACTION = 100.0
"""The largest |σ| and |ε| accepted, in units of a_max: a correction of 100 action bounds is
already nonsense, and a bound keeps every correction (and θ̂ after it) finite."""
MAX_BETA = 1e6
"""The largest rationality β accepted: β·θ*·g must stay finite for the Boltzmann choice."""


def _number(name: str, value: Any, rng: str) -> float:
    """``value`` as a float: a number or a numeric string ("0.1", as a command line gives it);
    never a bool (``True`` is not a noise level), else ValueError naming ``name``."""
    if isinstance(value, bool | np.bool_):
        raise ValueError(f"{name} must be {rng}, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {rng}, got {value!r}") from None


def check_fraction(name: str, value: float, *, allow_negative: bool = False) -> float:
    """Validate a noise or bias level given as a fraction of a_max, |value| <= MAX_FRACTION."""
    low = -MAX_FRACTION if allow_negative else 0.0
    rng = f"a number in [{low:g}, {MAX_FRACTION:g}] (a fraction of the action bound)"
    value = _number(name, value, rng)
    if not (np.isfinite(value) and low <= value <= MAX_FRACTION):
        raise ValueError(f"{name} must be {rng}, got {value}")
    return value


def check_beta(beta: Any) -> float:
    """Validate a rationality β: a number in [0, MAX_BETA]."""
    rng = f"a number in [0, {MAX_BETA:g}]"
    value = _number("beta", beta, rng)
    if not (np.isfinite(value) and 0.0 <= value <= MAX_BETA):
        raise ValueError(f"beta must be {rng}, got {value}")
    return value
