"""The authors' study learner's settings, expressed with this project's Tasks and learners.

What their learner did with a logged correction (poses x_0 … x_n in their logged frame): one
update per consecutive pair, θ ← θ + 1 · G(x_k, 3 (x_{k+1} − x_k)), with g = φ(x + u) − φ(x),
their φ = −(planar distance to the pitcher, distance to the plate, height[, ‖(roll′, pitch,
yaw)‖]) and no clipping of x + u. ``AuthorsStudyTask`` is that φ and f on our StudyTask (Task 1:
positions only), so our own One and Gradient rules run under their settings; α = 1.

Their StROL added their trained ĝ: θ ← θ + g(x, 3Δ) + λ·ĝ(x, 3Δ), λ = 0.25
(:class:`StROLPaperLearner`, on the same φ, with the ĝ read by :mod:`authors_ghat`).

Because none of these updates depends on θ̂, the θ̂0 a session started from follows from its
final θ̂: θ̂0 = θ̂_final − Σ updates (:func:`implied_theta0`). Their θ̂0 was uniform in
[−1, 1]^d, so an implied θ̂0 outside that box says the rule assumed is not the one that ran.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.authors_ghat import (
    FLAG,
    PAPER_LAMBDA,
    AuthorsGhat,
    load_authors_ghat,
)
from strol_gym.learners.protocol import LinearRuleLearner
from strol_gym.learners.registry import make_learner
from strol_gym.tasks.base import Task
from strol_gym.tasks.study import STUDY_TASKS, StudyTask

AUTHORS_ALPHA = 1.0
AUTHORS_GAIN = 3.0
"""Their learner's u: 3 × the step between consecutive logged poses."""
RULES = {"b1": "one", "b2": "gradient", "ours": "strol-paper"}
"""The rule each session ran, under which its θ̂0 is worked back (their MOF gate never rejected,
so its sessions ran the ungated gradient rule); StROL's needs their ĝ (``--authors-ghat``)."""
RULE_NAMES = {"b1": "One", "b2": "MOF", "ours": "StROL"}
"""How the check names each folder's rule."""
PAPER = "strol-paper"


class _AuthorsFeatures:
    """Their φ and f on a StudyTask: orientation −‖(roll′, pitch, yaw)‖, x + u not clipped."""

    oriented: bool
    pitcher: np.ndarray
    plate: np.ndarray

    def features(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        cols = [
            -np.linalg.norm(x[..., :2] - self.pitcher[:2], axis=-1),
            -np.linalg.norm(x[..., :3] - self.plate, axis=-1),
            -np.abs(x[..., 2]),
        ]
        if self.oriented:
            cols.append(-np.linalg.norm(x[..., 3:6], axis=-1))
        return np.stack(cols, axis=-1)

    def dynamics(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=np.float64) + u_r + u_h


class StROLPaperLearner(LinearRuleLearner):
    """The paper's StROL as the study ran it: G = g(x, u) + λ·ĝ(x, u), λ = 0.25, on the authors'
    φ (:func:`authors_task`) with their trained ĝ. Fed their per-sample pairs (x_k, 3Δx_k)."""

    name = PAPER

    def __init__(self, task: Task, ghat: AuthorsGhat) -> None:
        super().__init__(task)
        if not isinstance(ghat, AuthorsGhat) or ghat.layers[-1][1].shape != (task.dim,):
            raise ValueError(f"ghat must be the authors' ĝ for {task.task_id}")
        self.ghat = ghat
        self.lam = PAPER_LAMBDA

    def direction(self, x, u_h, u_r, theta) -> np.ndarray:
        return self.task.g(x, u_h, u_r) + self.lam * self.ghat(x, u_h)

    def config(self) -> dict[str, Any]:
        return {"lam": self.lam, "ghat_sha256": self.ghat.sha256}


def strol_paper(task: Task, authors_ghat: str | Path | None = None) -> StROLPaperLearner:
    """``strol-paper`` for a Study Task (built on its authors' φ): needs ``--authors-ghat``."""
    if authors_ghat is None:
        raise ValueError(
            f"{PAPER} needs the authors' ĝ: give {FLAG} GDIR (a checkout's user_study/g_data)"
        )
    number = getattr(task, "number", None)
    if not isinstance(task, StudyTask) or number not in STUDY_TASKS:
        raise ValueError(f"{PAPER} runs on the Study Tasks only, not {task.task_id}")
    return StROLPaperLearner(authors_task(number), load_authors_ghat(authors_ghat, number))


def authors_task(number: int) -> StudyTask:
    """Study Task ``number`` (1-3) with the authors' φ, f and α = 1."""
    base = STUDY_TASKS[number]
    cls = type(
        f"Authors{base.__name__}",
        (_AuthorsFeatures, base),
        {"task_id": f"authors-study-task{number}", "__module__": __name__},
    )
    return cls(alpha=AUTHORS_ALPHA)


def sample_updates(poses: np.ndarray, number: int) -> tuple[np.ndarray, np.ndarray]:
    """A correction's logged poses (n, 6) as their learner's (x_k, u_k = 3 Δx_k), k < n − 1
    (Task 1: positions only)."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
    if number == 1:
        poses = poses[:, :3]
    return poses[:-1], AUTHORS_GAIN * np.diff(poses, axis=0)


def rule_learner(rule: str, number: int, ghat: str | Path | None = None) -> LinearRuleLearner:
    """``rule`` ("one", "gradient" or "strol-paper", which needs GDIR ``ghat``) on Study Task
    ``number`` under the authors' settings."""
    if rule == PAPER:
        return strol_paper(STUDY_TASKS[number](), ghat)
    learner = make_learner(rule, task=authors_task(number))
    assert isinstance(learner, LinearRuleLearner)  # the built-in rules are
    return learner


def update_steps(
    corrections: list[np.ndarray], number: int, rule: str, ghat: str | Path | None = None
) -> list[np.ndarray]:
    """Per logged correction, the cumulative sum (n_k − 1, d) of the updates our ``rule`` learner
    makes on its consecutive sample pairs, counted from the session's start (θ̂ − θ̂0 after each
    sample) under the authors' settings; (0, d) for a correction of fewer than two poses (their
    loop over consecutive pairs makes no update). No update depends on θ̂."""
    learner = rule_learner(rule, number, ghat)
    task = learner.task
    learner.reset(np.zeros(task.dim))
    out = []
    for poses in corrections:
        steps = []
        if len(poses) >= 2:
            x, u = sample_updates(poses, number)
            for xk, uk in zip(x, u, strict=True):
                learner.update(xk, uk, np.zeros_like(uk))
                steps.append(np.array(learner.theta, dtype=np.float64))
        out.append(np.array(steps).reshape(len(steps), task.dim))
    return out


def summed_updates(
    corrections: list[np.ndarray], number: int, rule: str, ghat: str | Path | None = None
) -> np.ndarray:
    """Σ of the updates our ``rule`` learner makes on every logged sample pair, under the
    authors' settings (each update is independent of θ̂, so the sum starts from 0)."""
    steps = [s for s in update_steps(corrections, number, rule, ghat) if len(s)]
    return steps[-1][-1] if steps else np.zeros(authors_task(number).dim)


def implied_theta0(
    final: np.ndarray,
    corrections: list[np.ndarray],
    number: int,
    rule: str,
    ghat: str | Path | None = None,
) -> np.ndarray:
    """θ̂0 = final θ̂ − Σ updates, under ``rule`` ("one", "gradient" or "strol-paper" with GDIR
    ``ghat``) and the authors' settings."""
    return np.asarray(final, dtype=np.float64) - summed_updates(corrections, number, rule, ghat)


def reconstruct(
    final: np.ndarray,
    corrections: list[np.ndarray],
    number: int,
    rule: str,
    ghat: str | Path | None = None,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """The implied θ̂0 and θ̂ after each logged sample update of each correction (n_k − 1, d),
    from that θ̂0 forward under ``rule``: the θ̂ a session's learner held (their log keeps only
    the final one). The last row of the last non-empty correction is the logged final θ̂."""
    steps = update_steps(corrections, number, rule, ghat)
    nonempty = [s for s in steps if len(s)]
    theta0 = np.asarray(final, dtype=np.float64) - (nonempty[-1][-1] if nonempty else 0.0)
    return theta0, [theta0 + s for s in steps]


def reconstructed_theta_hats(
    final: np.ndarray,
    corrections: list[np.ndarray],
    number: int,
    rule: str,
    ghat: str | Path | None = None,
) -> list[np.ndarray]:
    """θ̂ after each logged sample update of each correction (:func:`reconstruct`)."""
    return reconstruct(final, corrections, number, rule, ghat)[1]


__all__ = [
    "AUTHORS_GAIN",
    "PAPER",
    "RULES",
    "RULE_NAMES",
    "StROLPaperLearner",
    "authors_task",
    "implied_theta0",
    "reconstruct",
    "reconstructed_theta_hats",
    "rule_learner",
    "sample_updates",
    "strol_paper",
    "update_steps",
]
