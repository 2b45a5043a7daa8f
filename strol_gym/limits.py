"""Fixed caps on the sizes a command line accepts, and the one option that lifts them.

A size (a batch, a grid, corrections per episode) is bounded by a documented constant, not by
what the machine's memory happens to allow: a typo fails at once with a message naming the
option and its cap, instead of after minutes or by exhausting memory. ``--allow-large`` lifts
the caps of the command it is given to (docs/benchmark.md lists them).
"""

from __future__ import annotations

import argparse

ALLOW_LARGE = "--allow-large"

TRAIN_CAPS = {
    "batch": 10_000,
    "steps": 1_000_000,
    "candidates": 1_024,
    "heldout": 50_000,
    "unroll": 100,
}
"""``train``: 100x the paper's batch of 100, a million Adam steps, 1,024 candidate actions,
50,000 held-out samples, K = 100 unrolled updates."""
BASIN_CAPS = {"grid": 201, "steps": 10_000}
"""``basin``: a 201 x 201 grid of θ̂0, 10,000 corrections."""
RUN_CAPS = {"corrections": 10_000}
"""``run``: 10,000 corrections per episode (the paper's envs use 5 and 10)."""


def add_allow_large(parser: argparse.ArgumentParser) -> None:
    """The option that lifts a command's fixed size caps (``check_size_caps``)."""
    parser.add_argument(
        ALLOW_LARGE,
        action="store_true",
        help="lift the fixed caps on sizes (docs/benchmark.md); memory is then yours to watch",
    )


def check_size_caps(args: argparse.Namespace, caps: dict[str, int]) -> None:
    """ValueError naming the option and its cap for a size above it, unless --allow-large."""
    if getattr(args, "allow_large", False):
        return
    for dest, cap in caps.items():
        value = getattr(args, dest, None)
        if value is not None and value > cap:
            flag = "--" + dest.replace("_", "-")
            raise ValueError(
                f"{flag} must be at most {cap:,} (a fixed cap; {ALLOW_LARGE} lifts it), "
                f"got {value:,}"
            )
