"""The experiments: one :class:`~strol_gym.benchmarks.experiments.base.BenchExperiment` per
``strol-bench`` subcommand that runs something, found through ``EXPERIMENTS``.

An experiment of one's own is one file: a subclass that fills the hooks, and
``register_experiment("name", MyExperiment)`` at import; ``strol-bench name --plugin file.py``
then runs it (docs/extending.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from strol_gym.registry import Registry

if TYPE_CHECKING:  # base imports the engine, which must not load with the registry
    from strol_gym.benchmarks.experiments.base import BenchExperiment

_EXPERIMENTS: dict[str, Any] = {
    "paper": "strol_gym.benchmarks.experiments.paper:Paper",
    "run": "strol_gym.benchmarks.experiments.run:Run",
    "study": "strol_gym.benchmarks.experiments.study:Study",
    "changing": "strol_gym.benchmarks.experiments.changing:Changing",
    "lambda": "strol_gym.benchmarks.experiments.lambda_sweep:LambdaSweep",
    "basin": "strol_gym.benchmarks.experiments.basin:Basin",
    "confirm": "strol_gym.benchmarks.experiments.confirm:Confirm",
    "robustness": "strol_gym.benchmarks.experiments.robustness:Robustness",
}


def _check(name: str, piece: Any) -> None:
    from strol_gym.benchmarks.experiments.base import BenchExperiment

    if not (isinstance(piece, type) and issubclass(piece, BenchExperiment)):
        raise ValueError(
            f"experiment {name!r} must be a BenchExperiment subclass or a 'module:attr' string, "
            f"got {piece!r}"
        )


EXPERIMENTS: Registry[type[BenchExperiment]] = Registry(
    "experiment",
    _EXPERIMENTS,
    check=_check,
    hint=" naming a BenchExperiment subclass",
    shared=False,
)


def register_experiment(name: str, experiment: Any) -> None:
    """Make ``experiment`` (a BenchExperiment subclass or "module:attr") the subcommand
    ``strol-bench name``."""
    EXPERIMENTS.register(name, experiment)


def make_experiment(name: str) -> Any:
    """An instance of the experiment registered as ``name`` (its subcommand is ``name``)."""
    cls = EXPERIMENTS.get(name)
    _check(name, cls)
    exp = cls()
    exp.name = name
    return exp
