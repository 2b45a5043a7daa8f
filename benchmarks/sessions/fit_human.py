"""``strol-bench fit-human SOURCE... --human NAME [--compare A,B,C] --out DIR``: fit a human
model to correction logs (the likelihood and its machinery:
``strol_gym.benchmarks.sessions.fitting``).

A SOURCE is a session log (.jsonl), a folder of them, or a Minari dataset (``strol-bench
export``). The fit reads only what a person's log holds (``fitting.Corrections``): the header's
Task (to compute φ and g) and, per episode, θ* and θ̂0; per correction x, u_H, u_R and θ̂ after
it. The person is the header's ``extra["participant"]`` or ``extra["user"]`` where a front end
logged one (``strol-bench import-study`` does), else each episode; θ̂ is unknown after a
correction whose ``theta_hat_after`` is null, and from the start where ``extra["unknown"]``
lists ``theta_hat0`` (the imported study sessions: models that teach relative to θ̂ are then
left out, saying so). Never the seeds, the env's kwargs (σ, the human) or
anything else of the header: a test strips them and gets the same estimate.

Writes DIR/fit.json (the named model: estimates, 95 % intervals over people (``--interval``),
log-likelihood, held-out log-likelihood; with ``--compare`` also the model the parsimony rule
selects and why, ``fitting.select``), DIR/fit.md, and with ``--compare`` DIR/compare.json,
a table of held-out log-likelihoods and DIR/plots/ppc.png: the real corrections against draws
of each fitted model at the same states, for the statistics the logs identify.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.fitting import (
    DEFAULT_INTERVAL,
    FEW_PEOPLE,
    INTERVALS,
    PARSIMONY_RULE,
    Corrections,
    Fit,
    Selection,
    best_for_theta,
    fit,
    select,
    simulate,
)
from strol_gym.files import write_figure, write_text_atomic

INTERVAL_NAMES = {
    "bca": "BCa bootstrap, widened for few people",
    "sandwich": "person-clustered sandwich (leave-one-person-out, CR3), t on at most G − 1 df",
    "percentile": "percentile bootstrap",
}

MAX_FILES = 10_000
MAX_FILE_BYTES = 200_000_000
"""A log larger than this is refused before it is read (sizes capped)."""


# ---------------------------------------------------------------------------- reading logs
def _sources(sources: Sequence[str]) -> list[str]:
    out: list[str] = []
    for s in sources:
        path = Path(s)
        if (
            path.is_dir()
            and not (path / "metadata.json").is_file()
            and not (path / "data" / "metadata.json").is_file()
        ):
            logs = sorted(str(p) for p in path.rglob("*.jsonl"))
            if not logs:
                raise ValueError(f"SOURCE {s}: a folder without session logs (*.jsonl)")
            out += logs
        else:
            out.append(s)
        if len(out) > MAX_FILES:
            raise ValueError(f"SOURCE: more than {MAX_FILES} logs")
    return out


def _extra(header: dict[str, Any]) -> dict[str, Any]:
    extra = header.get("extra")
    return extra if isinstance(extra, dict) else {}


def _person(header: dict[str, Any], source: str, episode: int) -> str:
    """Who made an episode's corrections: ``extra["participant"]`` or ``extra["user"]`` (the
    study importer's), else the episode itself."""
    extra = _extra(header)
    for key in ("participant", "user"):
        who = extra.get(key)
        if isinstance(who, str | int) and not isinstance(who, bool) and str(who):
            return f"participant {who}"
    return f"{source}#{episode}"


def _theta0_unknown(header: dict[str, Any]) -> bool:
    """Whether the log marks θ̂0 as not logged (its ``theta_hat0`` a placeholder)."""
    unknown = _extra(header).get("unknown")
    return isinstance(unknown, list) and "theta_hat0" in unknown


def _theta_reconstructed(header: dict[str, Any]) -> bool:
    """Whether the log's θ̂ is reconstructed rather than logged (``import-study --theta0
    implied`` on a One or MOF session: the header's ``extra["theta_hat"]`` says so)."""
    how = _extra(header).get("theta_hat")
    return isinstance(how, str) and how.startswith("reconstructed")


def load_corrections(sources: Sequence[str]) -> Corrections:
    """Every correction of ``sources`` (logs, folders, Minari ids) as a :class:`Corrections`;
    ValueError on a bad source, mixed Tasks, no θ* or too many corrections."""
    from strol_gym.benchmarks.sessions.export import read_any
    from strol_gym.wrappers.session_log import session_task

    if not sources:
        raise ValueError("SOURCE: give at least one session log, folder or Minari dataset")
    rows: dict[str, list[Any]] = {k: [] for k in ("x", "u_h", "u_r", "star", "hat", "k", "ep")}
    people: dict[str, int] = {}
    person: list[int] = []
    task, task_name, n_ep, unknown, rebuilt = None, None, 0, False, 0
    for src in _sources(sources):
        path = Path(src)
        if path.is_file() and path.stat().st_size > MAX_FILE_BYTES:
            raise ValueError(f"SOURCE {src}: larger than {MAX_FILE_BYTES // 1_000_000} MB")
        if not path.exists() and "/" not in src and src.endswith(".jsonl"):
            raise ValueError(f"SOURCE {src}: no such file")
        session = read_any(src)
        name = session.header["task"]
        if task is None:
            task, task_name = session_task(session), name
        elif name != task_name:
            raise ValueError(f"SOURCE {src}: task {name!r}, the others {task_name!r}")
        no_theta0 = _theta0_unknown(session.header)
        unknown |= no_theta0
        rebuilt += _theta_reconstructed(session.header)
        for e, ep in enumerate(session.episodes):
            if ep.theta_star is None:
                continue
            who = people.setdefault(_person(session.header, src, e), len(people))
            hat = np.asarray(ep.theta_hat0, dtype=np.float64)
            if no_theta0:
                hat = np.full_like(hat, np.nan)
            for i, c in enumerate(ep.corrections):
                rows["x"].append(c["x"])
                rows["u_h"].append(c["u_h"])
                rows["u_r"].append(c["u_r"])
                rows["star"].append(ep.theta_star)
                rows["hat"].append(hat)
                rows["k"].append(i)
                rows["ep"].append(n_ep)
                person.append(who)
                after = c["theta_hat_after"]
                unknown |= after is None
                hat = np.full_like(hat, np.nan) if after is None else after
            n_ep += 1
            if len(person) > _max_corrections():
                raise ValueError(
                    f"SOURCE: more than {_max_corrections():,} corrections (the cap "
                    "fit_corrections: a fit's memory grows with them; --allow-large lifts it)"
                )
    if not person:
        raise ValueError("SOURCE: no correction with a logged θ* (the preference taught)")
    assert task is not None
    return Corrections(
        task,
        np.array(rows["x"]),
        np.array(rows["u_h"]),
        np.array(rows["u_r"]),
        np.array(rows["star"]),
        np.array(rows["hat"]),
        np.array(rows["k"]),
        np.array(rows["ep"]),
        np.array(person),
        list(people),
        _hat_source(unknown, rebuilt),
    )


def _hat_source(unknown: bool, rebuilt: int) -> str:
    """How the corrections' θ̂ came to be known (``Corrections.theta_hat_source``)."""
    if rebuilt:
        part = ", unknown in the others" if unknown else ""
        return f"reconstructed (not logged) in {rebuilt} session(s){part}"
    return "logged, partly unknown" if unknown else "logged"


def _max_corrections() -> int:
    """The most corrections a fit reads: the caps table's ``fit_corrections`` (memory grows
    with them, ~0.4 MB each), or with the caps lifted the fitter's own bound."""
    from strol_gym.benchmarks.sessions.fitting import MAX_CORRECTIONS
    from strol_gym.limits import CAPS, lifted_now

    return MAX_CORRECTIONS if lifted_now() else CAPS["fit_corrections"]


# ---------------------------------------------------------------------------- statistics
def angle_to_best(data: Corrections, u: np.ndarray) -> np.ndarray:
    """Degrees between each correction and θ*'s best single correction at its state (the
    myopic person's choice; NaN for a zero correction)."""
    best = best_for_theta(data)
    a = np.asarray(data.task.action_bound)
    un, bn = u / a, best / a
    num = (un * bn).sum(axis=1)
    den = np.linalg.norm(un, axis=1) * np.linalg.norm(bn, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.degrees(np.arccos(np.clip(num / den, -1.0, 1.0)))


def statistics(data: Corrections, u: np.ndarray, best_angle: np.ndarray) -> dict[str, np.ndarray]:
    """The statistics the logs identify, for corrections ``u`` at ``data``'s states."""
    given = np.any(u != 0.0, axis=1)
    per_ep = np.bincount(data.episode[given], minlength=int(data.episode.max()) + 1)
    length = np.bincount(data.episode)
    where = data.k / np.maximum(length[data.episode] - 1, 1)
    return {
        "corrections per session": per_ep[length > 0].astype(float),
        "|u_H| / a_max": np.linalg.norm(u / np.asarray(data.task.action_bound), axis=1)[given],
        "angle to θ*'s best correction (°)": best_angle[given],
        "where along the session (0 first, 1 last)": where[given],
    }


def ppc_plot(path: Path, data: Corrections, fits: dict[str, Fit], seed: int) -> None:
    """Histograms of each statistic: the real corrections against one draw per fitted model."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    real = statistics(data, data.u_h, angle_to_best(data, data.u_h))
    sims = {}
    for name, f in fits.items():
        sub = _usable(name, data)
        u = simulate(name, sub, f.estimate, np.random.default_rng(seed))
        sims[name] = statistics(sub, u, angle_to_best(sub, u))
    fig, axes = plt.subplots(1, len(real), figsize=(4.2 * len(real), 3.4))
    for ax, key in zip(axes, real, strict=True):
        values = [v for v in [real[key], *[s[key] for s in sims.values()]] if len(v)]
        finite = np.concatenate(values)
        finite = finite[np.isfinite(finite)]
        bins = np.histogram_bin_edges(finite if len(finite) else [0, 1], bins=20)
        ax.hist(real[key][np.isfinite(real[key])], bins, density=True, color="0.6", label="real")
        for name, s in sims.items():
            v = s[key][np.isfinite(s[key])]
            if len(v):
                ax.hist(v, bins, density=True, histtype="step", lw=1.5, label=name)
        ax.set_title(key, fontsize=9)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    write_figure(fig, path, dpi=110)
    plt.close(fig)


def _usable(name: str, data: Corrections) -> Corrections:
    from strol_gym.benchmarks.sessions.fitting import family, usable

    return usable(family(name), data)[0]


# ---------------------------------------------------------------------------- reports
def _fmt(v: float | None) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{v:.4g}"


def _interval(f: Fit, k: str) -> str:
    lo, hi = f.ci95[k]
    return "–" if not (math.isfinite(lo) and math.isfinite(hi)) else f"[{_fmt(lo)}, {_fmt(hi)}]"


def fit_markdown(f: Fit, sources: Sequence[str]) -> str:
    lines = [
        f"# fit-human: `{f.model}`",
        "",
        f"{f.n_people} people (the intervals' and folds' unit), {f.n_corrections} corrections, "
        f"from "
        f"{len(sources)} source(s). Maximum likelihood; 95 % intervals over people "
        f"({INTERVAL_NAMES[f.interval]}).",
        "",
        "| parameter | estimate | 95 % interval |",
        "|---|---|---|",
    ]
    for k, v in f.estimate.items():
        lines.append(f"| {k} | {_fmt(v)} | {_interval(f, k)} |")
    lines += [
        "",
        f"log-likelihood {f.loglik:.2f}; held-out (folds over people) {_fmt(f.heldout_loglik)}",
    ]
    if f.note:
        lines += ["", f"Note: {f.note}."]
    return "\n".join(lines) + "\n"


def compare_markdown(
    fits: dict[str, Fit], skipped: dict[str, str], chosen: Selection | None = None
) -> str:
    lines = [
        "# Held-out log-likelihood (folds over people; higher is better)",
        "",
        "| model | corrections | held-out log-lik | per correction | log-lik (all) | parameters |",
        "|---|---|---|---|---|---|",
    ]
    ranked = sorted(fits.values(), key=lambda f: -(f.heldout_loglik or -math.inf))
    for f in ranked:
        held = f.heldout_loglik if f.heldout_loglik is not None else math.nan
        params = ", ".join(f"{k} {_fmt(v)} {_interval(f, k)}" for k, v in f.estimate.items())
        lines.append(
            f"| {f.model} | {f.n_corrections} | {held:.2f} | {held / f.n_corrections:.3f} | "
            f"{f.loglik:.2f} | {params} |"
        )
    for name, why in skipped.items():
        lines.append(f"| {name} | – | left out: {why} | | | |")
    lines += [
        "",
        "Models fitted to different corrections (θ̂-needing models drop those "
        "without θ̂) compare per correction only.",
    ]
    if chosen is not None:
        lines += ["", f"**Selected: `{chosen.chosen}`** by the parsimony rule ({PARSIMONY_RULE})."]
        lines += [f"- {step}" for step in chosen.steps]
    return "\n".join(lines) + "\n"


def run_fit_human(
    sources: Sequence[str],
    human: str,
    out: str | Path,
    compare: Sequence[str] = (),
    n_boot: int = 200,
    folds: int = 5,
    seed: int = 0,
    plots: bool = True,
    interval: str = DEFAULT_INTERVAL,
) -> dict[str, Fit]:
    """The command's work (module docstring); the fits by model name. ValueError where
    ``compare`` is asked of fewer than 2 people (held-out needs folds of people)."""
    from strol_gym.benchmarks.sessions.fitting import family

    for name in [human, *compare]:
        family(name)  # every name checked before any work
    data = load_corrections(sources)
    if compare and len(data.people) < 2:
        raise ValueError(
            f"--compare ranks models by held-out log-likelihood: {FEW_PEOPLE}; SOURCE holds "
            f"{len(data.people)} (give more logs)"
        )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fits: dict[str, Fit] = {}
    skipped: dict[str, str] = {}
    for name in dict.fromkeys([human, *compare]):
        try:
            fits[name] = fit(name, data, n_boot=n_boot, folds=folds, seed=seed, interval=interval)
        except ValueError as e:
            if name == human:
                raise
            skipped[name] = str(e)
    main = fits[human]
    chosen = select(fits) if compare else None
    record = main.to_json()
    if chosen is not None:
        record["selection"] = chosen.to_json()
    write_text_atomic(out / "fit.json", json.dumps(record, indent=2) + "\n")
    write_text_atomic(out / "fit.md", fit_markdown(main, sources))
    if chosen is not None:
        write_text_atomic(
            out / "compare.json",
            json.dumps(
                {
                    "fits": [f.to_json() for f in fits.values()],
                    "left_out": skipped,
                    "selection": chosen.to_json(),
                },
                indent=2,
            )
            + "\n",
        )
        write_text_atomic(out / "compare.md", compare_markdown(fits, skipped, chosen))
        if plots:
            ppc_plot(out / "plots" / "ppc.png", data, fits, seed)
    return fits


# ---------------------------------------------------------------------------- CLI
def add_parser(sub: Any) -> None:
    from strol_gym.benchmarks.args import add_allow_large, plugin_option, positive_int

    p = sub.add_parser(
        "fit-human",
        help="fit a human model to correction logs; compare models by held-out likelihood",
        description="Fit a registered human model to session logs (a .jsonl, a folder of them, "
        "or a Minari dataset id): maximum likelihood with the action bound's clipping in the "
        "likelihood, 95 % intervals over people, held-out log-likelihood over folds "
        "of people. Reads only x, u_H, u_R, θ* and θ̂ where logged. Writes OUT/fit.json and "
        "fit.md; --compare adds compare.md/json and posterior-predictive plots, and selects "
        'one model (fit.json\'s "selection": which and why) by the parsimony rule: '
        + PARSIMONY_RULE
        + ".",
    )
    p.add_argument("sources", nargs="+", metavar="SOURCE", help="session log, folder or dataset")
    p.add_argument("--human", required=True, help="the registered human model to fit")
    p.add_argument("--compare", default="", help="comma-separated models to fit and compare")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--bootstrap", type=positive_int("--bootstrap", 10_000, low=0), default=200)
    p.add_argument("--folds", type=positive_int("--folds", 100, low=2), default=5)
    p.add_argument("--seed", type=positive_int("--seed", low=0), default=0)
    p.add_argument(
        "--interval",
        choices=INTERVALS,
        default=DEFAULT_INTERVAL,
        help="95 %% intervals over people: sandwich (default: person-clustered Wald on the "
        "fitting scale, leave-one-person-out covariance, t on at most G - 1 df; no "
        "resampling), bca (bootstrap over people, "
        "bias-corrected and accelerated, widened for few people; --bootstrap resamples), "
        "percentile (plain bootstrap; under-covers with 12 people: docs/humans.md)",
    )
    p.add_argument("--no-plots", action="store_true")
    plugin_option(p)
    add_allow_large(p)


def command(args: Any, parser: Any) -> int:
    from strol_gym.benchmarks.args import check_size_caps

    check_size_caps(args, {})  # --allow-large lifts the cap on the corrections read
    compare = [c for c in args.compare.split(",") if c] if args.compare else []
    if args.compare and not compare:
        parser.error(f"--compare must name models (comma-separated), got {args.compare!r}")
    fits = run_fit_human(
        args.sources,
        args.human,
        args.out,
        compare,
        args.bootstrap,
        args.folds,
        args.seed,
        plots=not args.no_plots,
        interval=args.interval,
    )
    for f in fits.values():
        params = ", ".join(f"{k} {_fmt(v)} {_interval(f, k)}" for k, v in f.estimate.items())
        print(f"{f.model}: {params}; loglik {f.loglik:.2f}, held-out {_fmt(f.heldout_loglik)}")
        if f.note:
            print(f"  note: {f.note}")
    print(f"wrote {Path(args.out) / 'fit.json'}")
    return 0


__all__ = ["add_parser", "command", "load_corrections", "run_fit_human", "statistics"]
