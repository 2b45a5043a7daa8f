"""``strol-bench replay LOG --learners a,b``: feed a session's logged corrections to learners.

Corrections people gave one learner are data for every learner: each learner starts where the
logged one did (the episode's θ̂0) and updates on the logged (x, u_H, u_R) in order. It cannot
change what the person did next (the person reacted to the logged learner's robot); this is
offline evaluation on the logged corrections, not a new session.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions import authors_space
from strol_gym.benchmarks.sessions.authors_ghat import FLAG, ghat_dir
from strol_gym.benchmarks.sessions.authors_rules import PAPER
from strol_gym.benchmarks.sessions.export import read_any
from strol_gym.files import open_atomic, write_figure
from strol_gym.learners.protocol import LearnerFailed
from strol_gym.learners.registry import make_learner
from strol_gym.metrics import cos_error, error
from strol_gym.wrappers.session_log import Session, session_task

DEFAULT_LEARNERS = ["gradient", "one", "mof", "strol"]
"""What ``replay`` runs without ``--learners``."""


def replay_session(
    session: Session,
    learners: Sequence[str],
    learner_kwargs: dict[str, dict] | None = None,
    authors_ghat: str | None = None,
) -> dict[str, list[np.ndarray]]:
    """θ̂ after 0, 1, ..., n corrections of each episode, concatenated over episodes, per learner
    (a list of (n_e + 1, d) arrays, one per episode); ``strol-paper`` and ``NAME@authors`` in
    the authors' feature space (:mod:`authors_space`)."""
    task = session_task(session)
    out: dict[str, list[np.ndarray]] = {}
    for name in learners:
        kwargs = (learner_kwargs or {}).get(name, {})
        authors = authors_space.in_authors_space(name)
        if authors:
            learner = authors_space.build(name, task, authors_ghat, kwargs)
        else:
            learner = make_learner(name, task=task, **kwargs)
        curves = []
        for k, ep in enumerate(session.episodes):
            learner.reset(ep.theta_hat0.copy())
            thetas = [np.asarray(learner.theta, dtype=np.float64).copy()]
            for j, c in enumerate(ep.corrections):
                where = f"in episode {k}, correction {j} of {session.path}"
                if authors:  # this project's learners on the logged poses: errors name the log
                    authors_space.feed(learner, c, where)
                    thetas.append(np.asarray(learner.theta, dtype=np.float64).copy())
                    continue
                try:
                    learner.update(c["x"], c["u_h"], c["u_r"])
                except Exception as e:  # a user's learner may raise anything: say where
                    raise LearnerFailed.of(str(name), where, e) from None
                thetas.append(np.asarray(learner.theta, dtype=np.float64).copy())
            curve = np.array(thetas)
            _check_finite_errors(session, k, curve)
            curves.append(curve)
        out[name] = curves
    return out


def _check_finite_errors(session: Session, k: int, curve: np.ndarray) -> None:
    """ValueError naming the log and episode if an error to θ* cannot be computed (θ* or θ̂ so
    large that ‖θ* − θ̂‖ overflows): replay writes no inf or NaN error."""
    star = session.episodes[k].theta_star
    if star is None:
        return
    with np.errstate(over="ignore", invalid="ignore"):
        ok = np.isfinite(np.linalg.norm(curve - star, axis=1)).all()
    if not ok:
        raise ValueError(
            f"{session.path}: episode {k}: ‖θ* − θ̂‖ overflows (θ* = {star.tolist()!r:.60}, "
            "or θ̂ from the log's values): the values are too large to compare; "
            "this log cannot be replayed"
        )


def _fmt(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:+.3f}" for x in v) + ")"


def summary_rows(session: Session, results: dict[str, list[np.ndarray]]) -> list[dict[str, Any]]:
    """Per learner and episode: final θ̂, ‖θ* − θ̂‖ and 1 − cos (NaN without a logged θ*)."""
    rows = []
    for name, curves in results.items():
        for k, (ep, curve) in enumerate(zip(session.episodes, curves, strict=True)):
            final = curve[-1]
            star = ep.theta_star
            rows.append(
                {
                    "learner": name,
                    "episode": k,
                    "corrections": len(ep.corrections),
                    "theta_hat": final,
                    "error": np.nan if star is None else error(star, final),
                    "cos_error": np.nan if star is None else cos_error(star, final),
                }
            )
    return rows


def write_csv(path: Path, session: Session, results: dict[str, list[np.ndarray]]) -> None:
    """One row per learner, episode and correction count: θ̂ and its errors to θ*."""
    d = len(session.header["task_describe"]["feature_names"])
    with open_atomic(path, newline="") as f:
        w = csv.writer(f)
        w.writerow(
            ["learner", "episode", "correction"]
            + [f"theta_{i}" for i in range(d)]
            + ["error", "cos_error"]
        )
        for name, curves in results.items():
            for k, (ep, curve) in enumerate(zip(session.episodes, curves, strict=True)):
                for j, theta in enumerate(curve):
                    star = ep.theta_star
                    err = "" if star is None else f"{error(star, theta):.6g}"
                    cos = "" if star is None else f"{cos_error(star, theta):.6g}"
                    w.writerow([name, k, j, *(f"{t:.6g}" for t in theta), err, cos])


def plot_thetas(path: Path, session: Session, results: dict[str, list[np.ndarray]]) -> None:
    """θ̂_i over corrections, one panel per feature, one line per learner (last episode)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from strol_gym.benchmarks.analysis.plots import learner_color

    names = session.header["task_describe"]["feature_names"]
    fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 2.8), squeeze=False)
    star = session.episodes[-1].theta_star
    for i, ax in enumerate(axes[0]):
        for name, curves in results.items():
            color, label = learner_color(name), authors_space.label(name)
            ax.plot(curves[-1][:, i], marker=".", color=color, label=label)
        if star is not None:
            ax.axhline(star[i], color="k", ls="--", lw=1, label="θ*")
        ax.set_title(f"θ̂ {names[i]}")
        ax.set_xlabel("corrections")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    write_figure(fig, path, dpi=120)
    plt.close(fig)


def run_replay(
    log: str | Path,
    learners: Sequence[str],
    out: str | Path | None = None,
    learner_kwargs: dict[str, dict] | None = None,
    plots: bool = True,
    authors_ghat: str | None = None,
) -> tuple[list[dict[str, Any]], list[Path]]:
    """Replay ``log`` through ``learners``; print the table; write CSV (+ PNG) into ``out``."""
    session = read_any(log)
    session_task(session)  # a log naming code is refused before anything is written
    folder = (
        Path(out)
        if out is not None
        else Path(log).with_suffix("").with_name(Path(log).stem + "_replay")
    )
    try:  # before the replay, not after it
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OSError(f"--out {folder}: cannot create this folder ({e.strerror or e})") from None
    results = replay_session(session, learners, learner_kwargs, authors_ghat)
    rows = summary_rows(session, results)
    written = [folder / "replay.csv"]
    write_csv(written[0], session, results)
    if plots:
        written.append(folder / "replay_theta.png")
        plot_thetas(written[-1], session, results)
    h = session.header
    print(
        f"{session.path}: {h['env_id']} task {h['task']}, logged learner {h['learner']}, "
        f"{len(session.episodes)} episode(s), {session.n_corrections} correction(s)"
    )
    print(f"{'learner':16s} {'ep':>2s} {'n':>3s}  {'final θ̂':34s} {'error':>7s} {'1 − cos':>7s}")
    for r in rows:
        print(
            f"{authors_space.label(r['learner']):16s} {r['episode']:2d} {r['corrections']:3d}  "
            f"{_fmt(r['theta_hat']):34s} {r['error']:7.3f} {r['cos_error']:7.3f}"
        )
    for p in written:
        print(f"wrote {p}")
    return rows, written


__all__ = ["plot_thetas", "replay_session", "run_replay", "summary_rows", "write_csv"]


# ---------------------------------------------------------------------- CLI (strol-bench replay)
def add_parser(sub: Any) -> None:
    from strol_gym.benchmarks.args import learner_list, plugin_option

    p = sub.add_parser(
        "replay",
        help="feed a session log's corrections through learners (table, CSV, plot)",
        description="Replay the corrections of a session log (strol-bench interact, or any "
        "SessionLogger) through learners: each starts at the logged θ̂0 and updates on the "
        "logged (x, u_H, u_R). Prints final θ̂, error to the logged θ* and 1 − cos.",
    )
    p.add_argument(
        "log",
        help="a session log (.jsonl), a Minari dataset (strol-bench export), or a folder of "
        "session logs (every learner on every log, paired by session, with statistics)",
    )
    p.add_argument(
        "--learners",
        type=learner_list,
        default=None,
        help="comma-separated registered names or module:attr; NAME@authors runs NAME in the "
        "authors' feature space on an imported log's poses, strol-paper is the paper's StROL "
        f"(needs {FLAG}); default: {','.join(DEFAULT_LEARNERS)} (+ strol-paper with {FLAG})",
    )
    p.add_argument("--learner-kwargs", default=None, help='JSON, e.g. \'{"strol": {"lam": 0.5}}\'')
    p.add_argument("--out", default=None, help="output folder (default: LOG's name + _replay)")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--reference", default="strol", help="a folder's tests: this learner vs each")
    p.add_argument(
        "--task-version",
        type=int,
        choices=(0, 1),
        default=None,
        help="a folder's Study logs replayed with that version's Task (and its ĝ)",
    )
    p.add_argument(
        FLAG,
        dest="authors_ghat",
        default=None,
        metavar="GDIR",
        help="a local checkout's user_study/g_data: the authors' ĝ for the learner strol-paper",
    )
    plugin_option(p)


def command(args: Any, parser: Any) -> int:
    from strol_gym.benchmarks.args import check_learner_names, learner_kwargs
    from strol_gym.benchmarks.sessions import replay_folder

    if args.learners is None:
        args.learners = DEFAULT_LEARNERS + ([PAPER] if args.authors_ghat is not None else [])
    if args.authors_ghat is not None:
        ghat_dir(args.authors_ghat)
    check_learner_names(authors_space.check_names(args.learners, args.authors_ghat))
    if replay_folder.is_log_folder(args.log):
        return replay_folder.command(args, parser)
    kwargs = learner_kwargs(args.learner_kwargs, args.learners)
    run_replay(args.log, args.learners, args.out, kwargs, not args.no_plots, args.authors_ghat)
    return 0
