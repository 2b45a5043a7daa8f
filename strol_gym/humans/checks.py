"""Checks of the numbers every human model takes: noise and bias in units of a_max, and β."""

from __future__ import annotations

from strol_gym import checks

MAX_FRACTION = 100.0
"""The largest |σ| and |ε| accepted, in units of a_max: a correction of 100 action bounds is
already nonsense, and a bound keeps every correction (and θ̂ after it) finite."""
MAX_BETA = 1e6
"""The largest rationality β accepted: β·θ*·g must stay finite for the Boltzmann choice."""


def check_fraction(name: str, value: object, *, allow_negative: bool = False) -> float:
    """Validate a noise or bias level given as a fraction of a_max, |value| <= MAX_FRACTION;
    a numeric string ("0.1", as a command line gives it) is read as its number."""
    low = -MAX_FRACTION if allow_negative else 0.0
    return checks.fraction_of(name, value, low, MAX_FRACTION, "a fraction of the action bound")


def check_beta(beta: object) -> float:
    """Validate a rationality β: a number in [0, MAX_BETA]."""
    return checks.fraction_of("beta", beta, 0.0, MAX_BETA, "")
