"""The argument types and option groups every ``strol-bench`` command shares.

Each type checks its value when argparse reads it, so a bad argument exits with status 2 and a
message naming it and its valid range before any work starts.
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable, Sequence
from typing import Any

from strol_gym import checks
from strol_gym.benchmarks.engine.backends import add_backend_options
from strol_gym.benchmarks.engine.config import DEFAULT_BLOCK
from strol_gym.files import loads_json
from strol_gym.limits import CAPS, lift


def positive_int(name: str, high: int | None = None, *, low: int = 1) -> Callable[[str], int]:
    """An argparse type: an integer in [low, high] (low defaults to 1; no upper bound)."""

    def parse(text: str) -> int:
        try:
            value: object = int(text)  # out of range: the error quotes the number (got 1)
        except ValueError:
            value = text  # not an integer: it quotes the text (got 'x')
        return int(checks.number(name, value, low=low, high=high, integer=True))

    return checks.cli_type(parse)


def nonneg_int(name: str) -> Callable[[str], int]:
    """An argparse type: an integer >= 0."""
    return positive_int(name, low=0)


def fraction(name: str, allow_negative: bool = False) -> Callable[[str], float]:
    """σ or ε as a fraction of a_max, checked by the humans' own rule (one range everywhere)."""
    from strol_gym.humans import check_fraction

    return checks.cli_type(lambda text: check_fraction(name, text, allow_negative=allow_negative))


def beta(text: str) -> float:
    """An argparse type: a rationality β, checked by the humans' own rule."""
    from strol_gym.humans import check_beta

    try:
        return check_beta(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"--{e}") from None


def learner_list(text: str) -> list[str]:
    """An argparse type: comma-separated learner names (at least one)."""
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise argparse.ArgumentTypeError("learners must name at least one learner")
    return names


def check_learner_names(names: list[str] | tuple[str, ...]) -> None:
    """ValueError for a name that is neither registered nor an importable ``module:attr``."""
    from strol_gym.learners.registry import LEARNERS

    for name in names:
        LEARNERS.check_name(name)


def learner_kwargs(
    text: str | None, learners: Sequence[str] | None = None
) -> dict[str, dict[str, Any]]:
    """``--learner-kwargs``: a JSON object of constructor kwargs per learner (``{}`` for None);
    ValueError naming the option otherwise, or naming a learner not among ``learners`` (the
    ones the command runs: kwargs for another would be ignored without a word)."""
    if not text:
        return {}
    kwargs = loads_json(text, "--learner-kwargs")
    if not isinstance(kwargs, dict) or not all(isinstance(v, dict) for v in kwargs.values()):
        raise ValueError('--learner-kwargs must map learner names to objects: {"strol": {...}}')
    stray = [k for k in kwargs if learners is not None and k not in learners]
    if stray:
        raise ValueError(
            f"--learner-kwargs names {', '.join(map(repr, stray))}, not among the learners run "
            f"({', '.join(learners or [])})"
        )
    return kwargs


def float_list(name: str, *, low: float = 0.0) -> Callable[[str], list[float]]:
    """An argparse type: comma-separated finite numbers >= ``low``, at least one."""
    bound = "" if low == -math.inf else f" >= {low:g}"

    def parse(text: str) -> list[float]:
        out = []
        for tok in (t.strip() for t in text.split(",")):
            try:
                out.append(float(checks.number(name, tok, low=low, text=True)))
            except ValueError:
                raise ValueError(
                    f"{name} must be comma-separated finite numbers{bound}, got {tok!r}"
                ) from None
        if not out:
            raise ValueError(f"{name} must name at least one value")
        return out

    return checks.cli_type(parse)


def finite(name: str, *, low: float | None = None) -> Callable[[str], float]:
    """An argparse type: one finite number (>= ``low`` when given)."""
    return checks.cli_type(lambda text: float(checks.number(name, text, low=low, text=True)))


def unit_open(name: str) -> Callable[[str], float]:
    """An argparse type: a number strictly between 0 and 1 (a level or share)."""
    return checks.cli_type(
        lambda text: float(
            checks.number(name, text, low=0.0, high=1.0, low_open=True, high_open=True, text=True)
        )
    )


def json_object(name: str):
    """An argparse type: a JSON object (keyword arguments), else an error naming ``name``."""

    def parse(text: str) -> dict[str, Any]:
        try:
            value = loads_json(text, name)
        except ValueError as e:
            raise argparse.ArgumentTypeError(f"{e}; it must be a JSON object") from None
        if not isinstance(value, dict):
            raise argparse.ArgumentTypeError(f"{name} must be a JSON object, got {text!r}")
        return value

    return parse


def plugin_option(p: argparse.ArgumentParser) -> None:
    """``--plugin``: modules of user pieces, imported before the command runs."""
    p.add_argument(
        "--plugin",
        action="append",
        default=[],
        metavar="MODULE",
        help="import a module (or a .py file) that registers your own learners, humans, Tasks, "
        "conditions or experiments (repeatable); see docs/extending.md",
    )


def run_options(p: argparse.ArgumentParser) -> None:
    """The options of every command that runs a config through the runner (their sizes are
    checked against ``RUNNER_CAPS`` by the CLI, with ``--allow-large``)."""
    plugin_option(p)
    add_allow_large(p)
    p.add_argument("--out", default=None, help="results folder (default results/<preset>)")
    p.add_argument(
        "--jobs",
        type=positive_int("--jobs"),
        default=None,
        help="worker processes (default: every available CPU); results do not depend on it",
    )
    p.add_argument("--seed", type=nonneg_int("--seed"), default=0, help="first run seed (0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--force",
        action="store_true",
        help="delete an existing results folder made with another config and start over",
    )
    p.add_argument(
        "--block",
        type=positive_int("--block"),
        default=DEFAULT_BLOCK,
        help=f"run seeds per unit of work, batched together (default {DEFAULT_BLOCK})",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    add_backend_options(p)


# ---------------------------------------------------------------------------- size caps
# Fixed caps on the sizes a command line accepts, and the one option that lifts them. A size (a
# batch, a grid, corrections per episode) is bounded by a documented constant, not by what the
# machine's memory happens to allow: a typo fails at once with a message naming the option and
# its cap, instead of after minutes or by exhausting memory. ``--allow-large`` lifts the caps of
# the command it is given to (docs/benchmark.md lists them).

ALLOW_LARGE = "--allow-large"

TRAIN_CAPS = {
    "batch": 10_000,
    "steps": 1_000_000,
    "candidates": 1_024,
    "heldout": 50_000,
    "unroll": 100,
    "threads": CAPS["threads"],
}
"""``train``: 100x the paper's batch of 100, a million Adam steps, 1,024 candidate actions,
50,000 held-out samples, K = 100 unrolled updates."""
BASIN_CAPS = {"grid": 201, "steps": 10_000}
"""``basin``: a 201 x 201 grid of θ̂0, 10,000 corrections."""
RUN_CAPS = {"corrections": CAPS["corrections"]}
"""``run``: 10,000 corrections per episode (the paper's envs use 5 and 10)."""
JOBS_PER_CPU = 4
RUNNER_CAPS = {
    "block": CAPS["block"],
    "jobs": min(CAPS["jobs"], JOBS_PER_CPU * (os.cpu_count() or 1)),
    "lambdas": CAPS["lambdas"],
    "sigmas": CAPS["sigmas"],
}
"""Every command that runs the runner: run seeds per unit, worker processes (at most 4 per CPU
of this machine and 1,024), values in a ``--lambdas`` or ``--sigmas`` list (a list's length is
checked)."""


def add_allow_large(parser: argparse.ArgumentParser) -> None:
    """The option that lifts a command's fixed size caps (``check_size_caps``)."""
    parser.add_argument(
        ALLOW_LARGE,
        action="store_true",
        help="lift the fixed caps on sizes (docs/benchmark.md); memory is then yours to watch",
    )


def check_size_caps(args: argparse.Namespace, caps: dict[str, int]) -> None:
    """ValueError naming the option and its cap for a size above it, unless --allow-large
    (which also lifts the caps of ``strol_gym.limits`` for the whole command: learner and human
    kwargs, env sizes)."""
    if getattr(args, "allow_large", False):
        lift(True)
        return
    for dest, cap in caps.items():
        value = getattr(args, dest, None)
        if isinstance(value, list | tuple):
            value = len(value)
        if value is not None and value > cap:
            flag = "--" + dest.replace("_", "-")
            raise ValueError(
                f"{flag} must be at most {cap:,} (a fixed cap; {ALLOW_LARGE} lifts it), "
                f"got {value:,}"
            )
