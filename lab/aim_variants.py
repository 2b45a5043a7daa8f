"""Which parts of the aimed person the study's people need: held-out log-likelihood (4 folds of
people) of ``aimed`` with the rotation weighed or not, one size or two, per study Task.

    python lab/aim_variants.py LOGS                      # the held-out table
    python lab/aim_variants.py LOGS --shipped "V1;V2;V3"   # the values fitted-aimed ships

LOGS is a folder written by strol-bench import-study; V1-V3 the variants chosen per Task.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions import fitting as F
from strol_gym.benchmarks.sessions.fit_human import load_corrections
from strol_gym.benchmarks.sessions.fitting import Corrections
from strol_gym.humans.aim import emphasis_names

VARIANTS: dict[str, dict[str, float | str]] = {
    "all": {},
    "no emphasis": {"emphasis": "ones"},
    "turn 1": {"turn": 1.0},
    "one size": {"small_share": 0.0, "small_size": 1.0},
    "one size, turn 1": {"small_share": 0.0, "small_size": 1.0, "turn": 1.0},
    "no emphasis, reach 1.3": {"emphasis": "ones", "reach": 1.3},
    "no emphasis, reach 2": {"emphasis": "ones", "reach": 2.0},
    "no emphasis, reach 3": {"emphasis": "ones", "reach": 3.0},
    "no emphasis, reach 5": {"emphasis": "ones", "reach": 5.0},
    "no emphasis, reach 8": {"emphasis": "ones", "reach": 8.0},
    "no emphasis, one size, reach 3": {
        "emphasis": "ones",
        "reach": 3.0,
        "small_share": 0.0,
        "small_size": 1.0,
    },
    "no emphasis, one size, turn 1": {
        "emphasis": "ones",
        "small_share": 0.0,
        "small_size": 1.0,
        "turn": 1.0,
    },
}
"""Parameters held per variant (``"emphasis": "ones"``: every feature weight at 1). In Task 1
(no rotation) ``turn`` is no parameter: the variants that hold it are left out there."""


def fixed(data: Corrections, values: dict[str, float | str], task_number: int) -> F.Family:
    """``aimed`` with ``values`` held (its emphasis names known once it has met ``data``)."""
    fam: F.Family = F.family("aimed")
    fam.prepare(data)
    held = dict(values)
    if held.pop("emphasis", None) == "ones":
        held.update({k: 1.0 for k in emphasis_names(data.task)})
    for name, value in held.items():
        fam = F._Fixed(fam, name, float(value))
    return fam


def main(folder: str, tasks: tuple[int, ...] = (1, 2, 3), only: str = "") -> None:
    for t in tasks:
        data = load_corrections(sorted(str(p) for p in Path(folder).glob(f"*_task_{t}_*.jsonl")))
        for label, values in VARIANTS.items():
            if only and only not in label:
                continue
            if t == 1 and "turn" in values:
                continue
            fam = fixed(data, values, t)
            prep = F.prepare(fam, data)
            _, ll = F.maximise(fam, prep)
            held = F.heldout(fam, prep, data, 4, np.random.default_rng(1))
            print(f"Task {t} | {label} | {len(fam.params)} | {ll:.2f} | {held:.2f}", flush=True)


def shipped(folder: str, chosen: list[str]) -> dict[str, dict[str, Any]]:
    """The per-Task fit ``fitted-aimed`` ships: the ``chosen`` variant of each Task (that of
    highest held-out log-likelihood in ``main``'s table); [estimate, low, high] with the
    person-clustered sandwich intervals of ``fit-human``."""
    out = {}
    for t, label in zip((1, 2, 3), chosen, strict=True):
        values = VARIANTS[label]
        data = load_corrections(sorted(str(p) for p in Path(folder).glob(f"*_task_{t}_*.jsonl")))
        fam = fixed(data, values, t)
        prep = F.prepare(fam, data)
        mle, _ = F.maximise(fam, prep)
        ci = F.sandwich_intervals(fam, prep, data, mle)
        held = F.heldout(fam, prep, data, 4, np.random.default_rng(1))
        row = {k: [round(mle[k], 4), round(ci[k][0], 4), round(ci[k][1], 4)] for k in mle}
        held_at = {p.name: p for p in F.Aimed.base_params}
        row.update({k: [1.0, 1.0, 1.0] for k in emphasis_names(data.task) if k not in mle})
        row.update({k: [1.0, 1.0, 1.0] for k in held_at if k not in mle and k == "turn"})
        row.update(
            {k: [float(v), float(v), float(v)] for k, v in values.items() if k != "emphasis"}
        )
        out[f"study-task{t}"] = {**row, "heldout_loglik": round(held, 2)}
        print(f"study-task{t}", out[f"study-task{t}"], flush=True)
    return out


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[2] == "--shipped":
        shipped(sys.argv[1], sys.argv[3].split(";"))
    elif len(sys.argv) > 2:  # LOGS TASKS LABEL-PART: some variants of some Tasks
        main(sys.argv[1], tuple(int(t) for t in sys.argv[2].split(",")), sys.argv[3])
    else:
        main(sys.argv[1])
