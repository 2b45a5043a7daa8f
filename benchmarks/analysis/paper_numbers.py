"""The numbers the authors report, to set beside ours. A reference to compare against, never a
target: they come from the authors' released code, which differs from the paper and from us
(unbounded ĝ, greedy evaluation human, unpaired runs; docs/fidelity.md).

Sources, one per table (the paper's text gives only test statistics; its figures' numbers are in
the authors' repository, which the paper cites for "a tabular version"):

- ``PAPER``: the Fig. 4 tables (mean ± std) of the authors' repository README, as printed there
  (one value, a misprint, left out).
- ``PAPER_CHANGING``: bar heights read off the authors' changing-preference figure
  (``figs/ch_pref_noise_0.025_bias_0.0.png``), approximate.
- ``PAPER_LAMBDA``: bar heights read off the authors' λ figure (``figs/regret_gvar.png``), which
  shows λ = 0, 0.1, 1 and 10 only, approximate.
"""

from __future__ import annotations

from collections.abc import Sequence

from strol_gym.benchmarks.analysis import stats
from strol_gym.benchmarks.analysis.base import Analysis, display

PAPER: dict[tuple[str, str], dict[str, dict[str, tuple[float, float]]]] = {
    ("robot", "regret"): {
        "training": {
            "gradient": (0.18, 0.37),
            "one": (0.20, 0.38),
            "mof": (0.12, 0.29),
            "e2e": (3.69, 0.89),
            "strol": (0.001, 0.004),
        },
        "clean": {
            "gradient": (0.10, 0.26),
            "one": (0.14, 0.33),
            "mof": (0.06, 0.18),
            "e2e": (3.86, 0.95),
            "strol": (0.01, 0.08),
        },
        "noisy-biased": {
            "gradient": (0.77, 0.84),
            "one": (0.44, 0.68),
            "mof": (0.47, 0.59),
            "e2e": (3.25, 1.36),
            "strol": (0.16, 0.83),
        },
        "uniform-prior": {
            "gradient": (0.17, 0.47),
            "one": (0.18, 0.50),
            "mof": (0.18, 0.46),
            "e2e": (1.12, 0.49),
            "strol": (0.12, 0.34),
        },
    },
    ("highway", "error"): {
        "training": {
            "gradient": (0.59, 0.36),
            "one": (0.51, 0.37),
            "mof": (0.58, 0.36),
            "e2e": (0.48, 0.08),
            "strol": (0.31, 0.06),
        },
        "clean": {
            "gradient": (0.55, 0.36),
            "one": (0.53, 0.35),
            "mof": (0.56, 0.37),
            "e2e": (0.48, 0.08),
            "strol": (0.30, 0.08),
        },
        "noisy-biased": {
            "gradient": (1.18, 0.48),
            "one": (1.18, 0.41),
            "mof": (1.08, 0.48),
            "e2e": (1.18, 0.60),
            "strol": (1.09, 0.60),
        },
        "uniform-prior": {
            "gradient": (1.07, 0.43),
            "one": (1.10, 0.45),
            "mof": (1.01, 0.42),
            "e2e": (0.98, 0.40),
            # StROL left out: the source prints "0.10 ± 0.42", a mean that its own std and the
            # paper's text (no StROL advantage under the uniform prior) make a misprint.
        },
    },
}


PAPER_CHANGING: dict[str, dict[str, float]] = {
    "robot": {"gradient": 0.63, "one": 0.51, "mof": 0.65, "e2e": 2.93, "strol": 0.16},
}
"""Changing preferences (θ* for 2 corrections, then −θ* for 3; the authors' noise 0.025 absolute =
σ 0.25 of a_max), mean regret read off the authors' figure (approximate: ≈ values; spread only
as SEM bars)."""

PAPER_LAMBDA: dict[str, dict[float, float]] = {
    "bimodal": {0.0: 0.185, 0.1: 0.04, 1.0: 0.005, 10.0: 0.012},
    "uniform": {0.0: 0.135, 0.1: 0.11, 1.0: 0.10, 10.0: 0.51},
}
"""StROL's Robot regret at λ ∈ {0, 0.1, 1, 10} (the only λ the authors' figure shows) under the
designer's (bimodal) prior and the uniform prior, read off that figure (approximate)."""


def side_by_side(a: Analysis, env: str, metric: str, learners: Sequence[str]) -> list[str]:
    """Markdown: rows condition × source (ours / paper), columns learners, mean ± std (ours
    with the reference's directional marks, ``stats.mark``)."""
    paper = PAPER.get((env, metric), {})
    lines = [
        "| condition | source | " + " | ".join(display(learner) for learner in learners) + " |"
    ]
    lines.append("|---|---|" + "---|" * len(learners))
    for cond in [e.condition.name for e in a.config.experiments if e.env == env]:
        ours = []
        for learner in learners:
            c = a.cell(env, cond, learner, metric)
            mark = stats.mark(a.test(env, cond, learner, metric))
            ours.append("n/a" if c is None else f"{c['mean']:.3f} ± {c['std']:.3f}{mark}")
        lines.append(f"| {cond} | ours | " + " | ".join(ours) + " |")
        if cond in paper:
            ref = [paper[cond].get(learner) for learner in learners]
            cells = ["—" if r is None else f"{r[0]:g} ± {r[1]:g}" for r in ref]
            lines.append(f"| {cond} | paper | " + " | ".join(cells) + " |")
    return lines
