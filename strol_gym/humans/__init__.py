"""Simulated humans who correct the robot.

One interface serves every caller: a :class:`HumanModel` chooses the corrections of a whole
batch of people (states, θ*, θ̂ where the model needs it, candidates drawn from one generator),
and the envs' single-sample ``Human.act`` is its thin adapter :class:`ModelHuman`. Real and
simulated humans share the ``Human`` protocol, so a user can pass their own object to the envs.
Noise and bias are fractions of the action bound a_max (docs/benchmark.md, "Conditions"):
δ ~ N(ε·a_max, (σ·a_max)²).

- ``choices``: the batched choices (eq. M6, Boltzmann, driver) and the noise;
- ``model``: the interface (``HumanModel``, ``Draws``, ``ModelHuman``, ``Human``);
- ``models``: the built-in models; ``zoo``: the robustness zoo; ``registry``: names and
  builders; ``spec``: one value for a human and its arguments; ``teaching``: the loop.
"""

from strol_gym.humans.checks import MAX_BETA, MAX_FRACTION, check_beta, check_fraction
from strol_gym.humans.choices import (
    boltzmann_correction,
    driver_correction,
    optimal_correction,
    perturb,
)
from strol_gym.humans.findings import register_findings
from strol_gym.humans.model import (
    DEFAULT_CANDIDATES,
    Draws,
    Human,
    HumanModel,
    ModelHuman,
    needs_theta_hat,
)
from strol_gym.humans.models import (
    BoltzmannHuman,
    BoltzmannModel,
    ChangingHuman,
    ChangingModel,
    DriverHuman,
    DriverModel,
    NominalHuman,
    TeacherModel,
)
from strol_gym.humans.registry import (
    HUMAN_MODELS,
    HUMANS,
    SHARED_PARAMS,
    HumanFactory,
    PerSampleModel,
    _accepted,
    check_human_kwargs,
    human_factory,
    human_model,
    make_human,
    register_human,
)
from strol_gym.humans.spec import HumanSpec
from strol_gym.humans.teaching import teach

register_findings()  # the findings' models join the registry (strol_gym.humans.findings)

SimulatedHuman = ModelHuman
"""The base of the built-in simulated humans (the adapter of a ``HumanModel``)."""

__all__ = [
    "DEFAULT_CANDIDATES",
    "HUMANS",
    "HUMAN_MODELS",
    "MAX_BETA",
    "MAX_FRACTION",
    "SHARED_PARAMS",
    "BoltzmannHuman",
    "BoltzmannModel",
    "ChangingHuman",
    "ChangingModel",
    "Draws",
    "DriverHuman",
    "DriverModel",
    "Human",
    "HumanFactory",
    "HumanModel",
    "HumanSpec",
    "ModelHuman",
    "NominalHuman",
    "PerSampleModel",
    "SimulatedHuman",
    "TeacherModel",
    "_accepted",
    "boltzmann_correction",
    "check_beta",
    "check_fraction",
    "check_human_kwargs",
    "driver_correction",
    "human_factory",
    "human_model",
    "make_human",
    "needs_theta_hat",
    "optimal_correction",
    "perturb",
    "register_human",
    "teach",
]
