"""Simulated humans who correct the robot.

One interface serves every caller: a :class:`HumanModel` chooses the corrections of a whole
batch of people (states, θ*, θ̂ where the model needs it, candidates drawn from one generator),
and the envs' single-sample ``Human.act`` is its thin adapter :class:`SimulatedHuman`. Real and
simulated humans share the ``Human`` protocol, so a user can pass their own object to the envs.
Noise and bias are fractions of the action bound a_max (docs/benchmark.md, "Conditions"):
δ ~ N(ε·a_max, (σ·a_max)²).

The vocabulary, one name per idea:

- ``HumanModel``: what people of one kind do, batched (``XModel``: ``NominalModel``,
  ``BoltzmannModel``, ``DriverModel``, ``ChangingModel`` and the zoo's);
- ``HumanSpec``: which person an env or a benchmark asks for (a registered name and its
  arguments), validated;
- ``SimulatedHuman``: one person of a model behind the envs' single-sample ``Human.act``, the
  per-env adapter (``XHuman``: ``NominalHuman``, ``BoltzmannHuman``, ...);
- ``Human``: the protocol real and simulated people share.

Modules: ``choices`` (the batched choices: eq. M6, Boltzmann, driver; the noise),
``interface`` (``Human``, ``HumanModel``, ``Draws``, ``SimulatedHuman``), ``builtin`` (the
built-in models and their humans), ``zoo`` (the robustness zoo), ``registry`` (names and
builders), ``spec`` (``HumanSpec``), ``population`` (many people of one spec), ``teaching`` (the
loop).
"""

from strol_gym.humans.builtin import (
    BoltzmannHuman,
    BoltzmannModel,
    ChangingHuman,
    ChangingModel,
    DriverHuman,
    DriverModel,
    NominalHuman,
    NominalModel,
)
from strol_gym.humans.checks import MAX_BETA, MAX_FRACTION, check_beta, check_fraction
from strol_gym.humans.choices import (
    boltzmann_correction,
    driver_correction,
    optimal_correction,
    perturb,
)
from strol_gym.humans.findings import register_findings
from strol_gym.humans.interface import (
    DEFAULT_CANDIDATES,
    Draws,
    Human,
    HumanModel,
    SimulatedHuman,
    needs_theta_hat,
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
    "NominalHuman",
    "NominalModel",
    "PerSampleModel",
    "SimulatedHuman",
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
