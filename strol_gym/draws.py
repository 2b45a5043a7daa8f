"""One row of uniform draws from each of many numpy generators (a vector env's sub-envs and
people each draw from their own): ``rngs[b].random(out=out[b])`` for every b, in one compiled
call where that gives numpy's doubles and leaves each generator as numpy would
(``strol_gym.pcg64_fill``: the fast kernels on, every generator a ``PCG64``), else by
numpy, one call each."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from strol_gym.compiled import use_fast


def uniform_rows(rngs: Sequence[np.random.Generator], out: np.ndarray) -> np.ndarray:
    """Fills ``out`` (len(rngs), k), row b from ``rngs[b]``, and returns it."""
    if len(rngs) > 1 and use_fast():
        from strol_gym.pcg64_fill import addresses, fill

        states = addresses(rngs)
        if states is not None:
            fill(states, out)
            return out
    for rng, row in zip(rngs, out, strict=True):
        rng.random(out=row)
    return out
