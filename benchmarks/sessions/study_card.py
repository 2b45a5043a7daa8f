"""The data card of imported user-study logs: aggregates only, never a session's row.

    python -m strol_gym.benchmarks.sessions.study_card LOGS --out FOLDER

LOGS is a folder written by ``strol-bench import-study`` (one update per correction). Prints
(and writes ``FOLDER/card.md``) per-Task means and pooled quantiles of what the logs identify,
and draws their histograms (``FOLDER/study_data_card.png``):

- corrections per session (empty and one-pose corrections counted apart: no update comes of
  them), logged samples per correction;
- each correction's displacement (cm) and rotation (°) in our cup frame;
- its direction against θ*'s best correction at that pose: the cosine between u_H and the
  steepest ascent of θ*·φ at x, both in units of the Task's a_max per axis (u / a_max against
  a_max ⊙ ∇ₓ(θ*·φ)), and the share of corrections that raised θ*·φ (θ*·g(x, u_H, 0) > 0);
- where along the path it starts: the robot-path sample nearest its first pose (its index,
  and as a share of the session's path samples);
- the final θ̂ the authors' learner reached, per Task and learner (mean error and 1 − cos).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.replay_folder import find_logs
from strol_gym.files import read_regular, write_figure, write_text_atomic
from strol_gym.metrics import cos_error, error
from strol_gym.tasks.study import StudyTask
from strol_gym.wrappers.session_log import read_session, session_task

QUANTILES = (10, 25, 50, 75, 90)


def _records(path: Path) -> list[dict[str, Any]]:
    """The log's lines as objects (after :func:`read_session` has checked the file)."""
    text = read_regular(path).decode("utf-8")
    return [json.loads(line) for line in text.splitlines() if line]


def collect(folder: str | Path) -> dict[str, dict[int, list[float]] | Any]:
    """Per quantity, per study Task, the values of every session or correction."""
    out: dict[str, Any] = defaultdict(lambda: defaultdict(list))
    finals: dict[tuple[int, str], list[tuple[float, float]]] = defaultdict(list)
    for path in find_logs(folder):
        session = read_session(path)
        task = session_task(session)
        if not isinstance(task, StudyTask):
            raise ValueError(f"{path}: a study card reads Study sessions, not {task.task_id}")
        recs = _records(path)
        ep = next(r for r in recs if r["type"] == "episode")
        number = int(session.header["extra"]["study_task"])
        star = np.asarray(ep["theta_star"], dtype=np.float64)
        out["corrections"][number].append(ep["corrections_logged"])
        out["empty"][number].append(ep["corrections_empty"])
        out["one_pose"][number].append(ep["corrections_one_pose"])
        out["samples"][number] += [0] * ep["corrections_empty"] + [1] * ep["corrections_one_pose"]
        bound = np.asarray(task.action_bound, dtype=np.float64)
        for c in (r for r in recs if r["type"] == "correction"):
            x, u = np.asarray(c["x"]), np.asarray(c["u_h"])
            out["samples"][number].append(c["samples"])
            out["displacement_cm"][number].append(float(np.linalg.norm(u[:3]) * 100.0))
            out["rotation_deg"][number].append(c["rotation_deg"])
            grad = task.feature_jacobian(x).T @ star
            a, b = u / bound, grad * bound
            denom = np.linalg.norm(a) * np.linalg.norm(b)
            out["cos_best"][number].append(float(a @ b / denom) if denom > 0 else np.nan)
            gain = float(star @ task.g(x[None], u[None], np.zeros((1, len(u))))[0])
            out["raised"][number].append(float(gain > 0))
            out["path_sample"][number].append(c["path_sample"])
            out["path_share"][number].append(c["path_sample"] / c["path_samples"])
        final = ep["theta_hat_final_logged"]
        if final is not None:
            f = np.asarray(final, dtype=np.float64)
            finals[(number, session.header["learner"])].append((error(star, f), cos_error(star, f)))
    out["finals"] = finals
    return out


def _q(values: list[float]) -> str:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return " / ".join(f"{q:.2f}" for q in np.percentile(v, QUANTILES)) if len(v) else "n/a"


ROWS = (
    ("corrections", "corrections per session"),
    ("samples", "logged samples per correction"),
    ("displacement_cm", "displacement per correction (cm)"),
    ("rotation_deg", "rotation per correction (°)"),
    ("cos_best", "cos(u_H, θ*'s best correction)"),
    ("raised", "share raising θ*·φ"),
    ("path_sample", "start along the path (sample index)"),
    ("path_share", "start along the path (share of samples)"),
)


def card_markdown(data: dict[str, Any]) -> str:
    """The card's tables: per-Task means, pooled quantiles, the authors' final θ̂."""
    tasks = sorted(data["corrections"])
    n_sess = {t: len(data["corrections"][t]) for t in tasks}
    n_corr = {t: int(sum(data["corrections"][t])) for t in tasks}
    lines = [
        "| | "
        + " | ".join(f"Task {t}" for t in tasks)
        + " | all: p10 / p25 / median / p75 / p90 |",
        "|---|" + "---|" * (len(tasks) + 1),
        "| sessions | " + " | ".join(str(n_sess[t]) for t in tasks) + " | |",
        "| corrections logged | " + " | ".join(str(n_corr[t]) for t in tasks) + " | |",
        "| of which empty / one pose | "
        + " | ".join(f"{sum(data['empty'][t])} / {sum(data['one_pose'][t])}" for t in tasks)
        + " | |",
    ]
    for key, label in ROWS:
        means = []
        for t in tasks:
            v = np.asarray(data[key][t], dtype=np.float64)
            means.append(f"{np.nanmean(v):.2f}" if len(v) else "n/a")
        pooled = [v for t in tasks for v in data[key][t]]
        spread = _q(pooled) if key != "raised" else f"{np.mean(pooled):.2f} (a share)"
        lines.append(f"| {label} (mean) | " + " | ".join(means) + f" | {spread} |")
    lines += ["", "| Task | learner | sessions | error ‖θ* − θ̂‖ (mean ± sd) | 1 − cos |"]
    lines.append("|---|---|---|---|---|")
    for (t, learner), vals in sorted(data["finals"].items()):
        e, c = np.array(vals).T
        sd = f" ± {e.std(ddof=1):.2f}" if len(e) > 1 else ""
        lines.append(f"| {t} | {learner} | {len(e)} | {e.mean():.2f}{sd} | {c.mean():.2f} |")
    return "\n".join(lines) + "\n"


def plot_card(path: Path, data: dict[str, Any]) -> None:
    """Histograms of the card's quantities, one colour per Task."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(14, 5.6))
    tasks = sorted(data["corrections"])
    for ax, (key, label) in zip(axes.flat, ROWS, strict=False):
        pooled = np.asarray([v for t in tasks for v in data[key][t]], dtype=np.float64)
        pooled = pooled[np.isfinite(pooled)]
        bins = np.histogram_bin_edges(pooled, bins=20) if len(pooled) else 10
        for t in tasks:
            v = np.asarray(data[key][t], dtype=np.float64)
            ax.hist(v[np.isfinite(v)], bins=bins, alpha=0.5, label=f"Task {t}")
        ax.set_title(label, fontsize=9)
    axes.flat[0].legend(fontsize=8)
    for ax in axes.flat[len(ROWS) :]:
        ax.axis("off")
    fig.suptitle("The authors' user study (12 participants × 3 Tasks × 3 learners): aggregates")
    fig.tight_layout()
    write_figure(fig, path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("logs", help="a folder written by strol-bench import-study")
    p.add_argument("--out", required=True, help="folder for card.md and study_data_card.png")
    args = p.parse_args(argv)
    data = collect(args.logs)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text = card_markdown(data)
    write_text_atomic(out / "card.md", text)
    plot_card(out / "study_data_card.png", data)
    print(text)
    print(f"wrote {out / 'card.md'} and {out / 'study_data_card.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
