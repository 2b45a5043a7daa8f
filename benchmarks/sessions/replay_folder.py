"""``strol-bench replay FOLDER``: every learner on every session log of a folder, paired.

Each learner is built once per Task and, for each session, starts from that session's logged
θ̂0 (``import-study`` writes the Task prior's mean, or the implied θ̂0 where the session's rule
allows it) and updates on the logged corrections in order. Per session and learner: the final
error ‖θ* − θ̂‖, 1 − cos(θ*, θ̂) and regret (eq. S1, both plans by the Task's planner from the
Task's start, its home). Sessions are the subjects of a within-subject design: per Task and
metric, the suite's RM-ANOVA across learners and Holm-corrected paired tests of the reference
learner against each other one (:mod:`strol_gym.benchmarks.analysis.stats`).

This is off-policy: each person corrected *that session's* robot, whose motion followed its own
θ̂; a learner replayed here would have moved differently and been corrected differently.

``--task-version 1`` replays a v0 Task's logs with the same-numbered StROL-Study-v1 Task, so
learners with a ĝ use the one trained for v1's corrections; a learner with no ĝ for the Task it
is given is left out, with a note.

``strol-paper`` (the paper's StROL, with ``--authors-ghat GDIR``) and ``NAME@authors`` run in
the authors' feature space on the logged poses in their hand frame (:mod:`authors_space`);
their regret is undefined (NaN: no planner in that space) and left out of regret's tests.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.analysis.stats import compare_to_reference, describe, rm_anova
from strol_gym.benchmarks.sessions import authors_space
from strol_gym.benchmarks.sessions.authors_ghat import AuthorsGhat
from strol_gym.files import open_atomic, write_figure, write_text_atomic
from strol_gym.learners.protocol import LearnerFailed
from strol_gym.learners.registry import make_learner
from strol_gym.metrics import cos_error, episode_regret, error
from strol_gym.tasks.base import Task
from strol_gym.wrappers.session_log import Session, read_session, session_task

METRICS = ("error", "cos_error", "regret")
LABELS = {"error": "error ‖θ* − θ̂‖", "cos_error": "1 − cos(θ*, θ̂)", "regret": "regret"}
MAX_LOGS = 100_000


def find_logs(folder: str | Path) -> list[Path]:
    """The ``*.jsonl`` files under ``folder`` (sorted); ValueError if there are none."""
    folder = Path(folder)
    logs = sorted(p for p in folder.rglob("*.jsonl") if p.is_file())
    if not logs:
        raise ValueError(f"{folder}: no session logs (*.jsonl) in this folder")
    if len(logs) > MAX_LOGS:
        raise ValueError(f"{folder}: {len(logs)} logs, at most {MAX_LOGS}")
    return logs


def is_log_folder(path: str | Path) -> bool:
    """A folder holding session logs (a Minari dataset folder holds none)."""
    p = Path(path)
    return p.is_dir() and any(p.rglob("*.jsonl"))


def versioned(task: Task, version: int | None) -> Task:
    """``task`` as version ``version`` of its Task (None: as logged)."""
    if version is None or task.version == version:
        return task
    from strol_gym.tasks.study import STUDY_TASK_SETS, StudyTask

    if isinstance(task, StudyTask) and version in (0, 1):  # the versions of the same Tasks
        return STUDY_TASK_SETS[version][task.number]()
    raise ValueError(f"--task-version {version}: {task.task_id} has no version {version}")


def _build(
    names: Sequence[str], task: Task, kwargs: dict[str, dict], authors_ghat: str | None = None
) -> tuple[dict[str, Any], dict[str, str]]:
    """Each learner built for ``task``; one without a ĝ for it is left out with a note."""
    built, notes = {}, {}
    for name in names:
        try:
            if authors_space.in_authors_space(name):
                built[name] = authors_space.build(name, task, authors_ghat, kwargs.get(name, {}))
            else:
                built[name] = make_learner(name, task=task, **kwargs.get(name, {}))
        except FileNotFoundError as e:
            notes[name] = str(e).split(";")[0].rsplit(" in ", 1)[0]
    return built, notes


def g_hat_source(learner: Any) -> str:
    """Which ĝ a learner uses: its checkpoint's file and the Task id it was trained for (the
    authors' ĝ: its file and SHA-256's start)."""
    ghat = getattr(learner, "ghat", None)
    if isinstance(ghat, AuthorsGhat):
        return f"authors' {ghat.path.name} ({ghat.sha256[:12]})"
    path = getattr(learner, "checkpoint", None)
    if path is None:
        return "none" if getattr(learner, "model", None) is None else "in memory"
    meta = getattr(learner, "checkpoint_meta", None) or {}
    return f"{Path(path).name} ({meta.get('task', {}).get('task_id', '?')})"


def final_theta(learner: Any, name: str, session: Session) -> np.ndarray:
    """θ̂ after the session's corrections, from its logged θ̂0 (every episode in turn)."""
    authors = authors_space.in_authors_space(name)
    for ep in session.episodes:
        learner.reset(ep.theta_hat0.copy())
        for j, c in enumerate(ep.corrections):
            where = f"in correction {j} of {session.path}"
            if authors:
                authors_space.feed(learner, c, where)
                continue
            try:
                learner.update(c["x"], c["u_h"], c["u_r"])
            except Exception as e:  # a user's learner may raise anything: say where
                raise LearnerFailed.of(name, where, e) from None
    return np.asarray(learner.theta, dtype=np.float64).copy()


def replay_group(
    sessions: list[Session],
    task: Task,
    names: Sequence[str],
    kwargs: dict[str, dict],
    authors_ghat: str | None = None,
) -> dict[str, Any]:
    """One Task's sessions through every learner: per learner, (n,) arrays of each metric."""
    built, notes = _build(names, task, kwargs, authors_ghat)
    stars = np.array([s.episodes[-1].theta_star for s in sessions], dtype=np.float64)
    start = getattr(task, "start", None)  # the Study Tasks' (and the Robot's) fixed start
    if start is None:
        raise ValueError(f"replay needs a Task with a fixed start state, got {task.task_id}")
    x0 = np.tile(start, (len(sessions), 1))
    group: dict[str, Any] = {"task": task, "sessions": sessions, "notes": notes}
    group["g_hat"] = {n: g_hat_source(le) for n, le in built.items()}

    def scores(finals: np.ndarray, planned: bool = True) -> dict[str, np.ndarray]:
        return {
            "error": np.array([error(a, b) for a, b in zip(stars, finals, strict=True)]),
            "cos_error": np.array([cos_error(a, b) for a, b in zip(stars, finals, strict=True)]),
            "regret": np.array(episode_regret(task, finals, stars, x0))
            if planned
            else np.full(len(finals), np.nan),
        }

    # Where every learner starts: what the corrections have to improve on (not tested).
    group["start"] = scores(np.array([s.episodes[0].theta_hat0 for s in sessions]))
    group["metrics"] = {}
    for name, learner in built.items():
        finals = np.array([final_theta(learner, name, s) for s in sessions])
        group["metrics"][name] = scores(finals, not authors_space.in_authors_space(name))
    return group


def group_stats(group: dict[str, Any], reference: str) -> list[dict[str, Any]]:
    """Per metric: the RM-ANOVA across learners and the reference's Holm-corrected tests."""
    rows: list[dict[str, Any]] = []
    for metric in METRICS:  # a learner without the metric (regret in the authors' φ) is left out
        names = [n for n, ms in group["metrics"].items() if np.isfinite(ms[metric]).any()]
        if len(names) < 2:
            continue
        y = np.column_stack([group["metrics"][n][metric] for n in names])
        keep = np.isfinite(y).all(axis=1)
        a = rm_anova(y[keep])
        rows.append({"metric": metric, "test": "rm-anova", "n": a.n, "F": a.F, "p_gg": a.p_gg})
        if reference not in names:
            continue
        for r in compare_to_reference(y[keep], names, reference):
            rows.append({"metric": metric, **r})
    return rows


def load_groups(folder: str | Path, version: int | None) -> dict[str, tuple[Task, list[Session]]]:
    """The folder's logs grouped by Task (its registry name), each Task resolved once."""
    groups: dict[str, tuple[Task, list[Session]]] = {}
    for path in find_logs(folder):
        s = read_session(path)
        if s.episodes[-1].theta_star is None:
            raise ValueError(f"{path}: no logged θ* (the replay scores against it)")
        name = s.header["task"]
        if name not in groups:
            groups[name] = (versioned(session_task(s), version), [])
        else:
            session_task(s)  # its dimensions checked like the first's
        groups[name][1].append(s)
    return groups


def _cell(values: np.ndarray) -> str:
    if not np.isfinite(values).any():
        return "n/a"
    d = describe(values)
    return f"{d['mean']:.3f} ± {d['std']:.3f}" if d["n"] > 1 else f"{d['mean']:.3f}"


def _p_cell(stats: list[dict[str, Any]], metric: str, name: str, reference: str) -> str:
    if name == reference:  # the reference of a metric it has no values of is no reference
        return "ref." if any(r.get("baseline") and r["metric"] == metric for r in stats) else ""
    for r in stats:
        if r["metric"] == metric and r.get("baseline") == name:
            p = r["p_holm"]
            return "n/a" if not math.isfinite(p) else ("< 0.001" if p < 0.001 else f"{p:.3f}")
    return ""


def markdown_table(groups: dict[str, dict[str, Any]], reference: str) -> str:
    """Per Task and learner: mean ± sd of each metric, Holm p vs the reference, and the ĝ."""
    lines = []
    for tname, g in groups.items():
        n = len(g["sessions"])
        lines.append(f"**{tname}** ({g['task'].task_id}, {n} sessions)\n")
        head = "| learner | ĝ | " + " | ".join(f"{LABELS[m]} | p (Holm)" for m in METRICS) + " |"
        lines += [head, "|" + "---|" * (2 + 2 * len(METRICS))]
        for name, ms in g["metrics"].items():
            cells = [authors_space.label(name), g["g_hat"][name]]
            for m in METRICS:
                cells += [_cell(ms[m]), _p_cell(g["stats"], m, name, reference)]
            lines.append("| " + " | ".join(cells) + " |")
        cells = ["(θ̂0: no update)", ""]
        for m in METRICS:
            cells += [_cell(g["start"][m]), ""]
        lines.append("| " + " | ".join(cells) + " |")
        for m in METRICS:
            for r in g["stats"]:
                if r["metric"] == m and r["test"] == "rm-anova":
                    p = r["p_gg"]
                    ptxt = "n/a" if not math.isfinite(p) else f"{p:.3g}"
                    lines.append(f"\nRM-ANOVA {LABELS[m]}: F = {r['F']:.2f}, p (GG) = {ptxt}")
        for name, note in g["notes"].items():
            lines.append(f"\n{authors_space.label(name)} left out: {note}.")
        if any(authors_space.in_authors_space(n) for n in g["metrics"]):
            lines.append(
                "\nRows marked (authors' φ) run in the authors' feature space on their logged "
                "poses: regret n/a (no planner in that space)."
            )
        lines.append("")
    return "\n".join(lines)


def write_outputs(folder: Path, groups: dict[str, dict[str, Any]], reference: str) -> list[Path]:
    """Per-session CSV, statistics CSV and the markdown table (into ``folder``)."""
    per = folder / "replay_sessions.csv"
    with open_atomic(per, newline="") as f:
        w = csv.writer(f)
        w.writerow(["task", "session", "learner", *METRICS])
        for tname, g in groups.items():
            for name, ms in g["metrics"].items():
                for i, s in enumerate(g["sessions"]):
                    vals = [f"{ms[m][i]:.6g}" for m in METRICS]
                    w.writerow([tname, s.path.name, name, *vals])
    stats = folder / "replay_stats.csv"
    keys = ["task", "metric", "test", "learner", "baseline", "n", "mean_diff", "p_raw"]
    keys += ["p_holm", "wilcoxon_p_holm", "effect_size", "F", "p_gg"]
    with open_atomic(stats, newline="") as f:
        dw = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        dw.writeheader()
        for tname, g in groups.items():
            for r in g["stats"]:
                dw.writerow({"task": tname, **r})
    table = folder / "replay.md"
    write_text_atomic(table, markdown_table(groups, reference))
    return [per, stats, table]


def plot_groups(path: Path, groups: dict[str, dict[str, Any]]) -> None:
    """One row per Task, one panel per metric: each learner's sessions as a box."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from strol_gym.benchmarks.analysis.plots import learner_color

    rows = len(groups)
    fig, axes = plt.subplots(rows, 3, figsize=(12, 2.9 * rows), squeeze=False)
    for r, (tname, g) in enumerate(groups.items()):
        names = list(g["metrics"])
        for c, m in enumerate(METRICS):
            ax = axes[r][c]
            data = [g["metrics"][n][m][np.isfinite(g["metrics"][n][m])] for n in names]
            box = ax.boxplot(data, patch_artist=True, showfliers=False)
            for patch, n in zip(box["boxes"], names, strict=True):
                patch.set_facecolor(learner_color(n))
                patch.set_alpha(0.6)
            ax.set_xticks(range(1, len(names) + 1), [authors_space.label(n) for n in names])
            ax.tick_params(axis="x", labelrotation=60, labelsize=7)
            ax.set_title(f"{tname}: {LABELS[m]}", fontsize=9)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)
    plt.close(fig)


def run_folder(
    folder: str | Path,
    learners: Sequence[str],
    out: str | Path | None = None,
    learner_kwargs: dict[str, dict] | None = None,
    plots: bool = True,
    reference: str = "strol",
    version: int | None = None,
    authors_ghat: str | None = None,
) -> tuple[dict[str, dict[str, Any]], list[Path]]:
    """Replay every log under ``folder``; print the table; write CSVs, table (+ PNG) to ``out``."""
    if reference not in learners:
        raise ValueError(f"--reference {reference!r} must be one of --learners {list(learners)}")
    loaded = load_groups(folder, version)
    dest = Path(out) if out is not None else Path(str(Path(folder).resolve()) + "_replay")
    try:
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OSError(f"--out {dest}: cannot create this folder ({e.strerror or e})") from None
    groups = {}
    for tname, (task, sessions) in loaded.items():
        g = replay_group(sessions, task, learners, learner_kwargs or {}, authors_ghat)
        g["stats"] = group_stats(g, reference)
        groups[tname] = g
    written = write_outputs(dest, groups, reference)
    if plots:
        written.append(dest / "replay.png")
        plot_groups(written[-1], groups)
    print(markdown_table(groups, reference))
    for p in written:
        print(f"wrote {p}")
    return groups, written


def command(args: Any, parser: Any) -> int:
    """``strol-bench replay FOLDER`` (the replay parser's arguments)."""
    from strol_gym.benchmarks.args import learner_kwargs

    run_folder(
        args.log,
        args.learners,
        args.out,
        learner_kwargs(args.learner_kwargs, args.learners),
        plots=not args.no_plots,
        reference=args.reference,
        version=args.task_version,
        authors_ghat=args.authors_ghat,
    )
    return 0


__all__ = ["find_logs", "is_log_folder", "replay_group", "run_folder"]
