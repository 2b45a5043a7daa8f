"""``strol-bench import-study DIR --out OUT``: the authors' user-study logs as session logs.

DIR is a ``user_study/data`` tree in the authors' layout: ``user_K/task_J/ALG/data.pkl``
(K a number, J 1-3, ALG ``b1`` = One, ``b2`` = MOF, ``ours`` = StROL); other folders
(``user_pilot``, ``user_test``) are not participants and are skipped. Each pickle is read by
:mod:`plain_pickle` (numeric arrays, lists, dicts and numbers only) and checked before use.

Each session becomes one session log (``wrappers/session_log.py``), ``OUT/user_K_task_J_ALG.jsonl``,
in the Study Task's frame and orientation convention (:mod:`authors_frame`):

- one ``correction`` line per physical correction with at least two logged poses: x = the cup's
  pose at its first logged pose, u_H = last − first (angles wrapped), u_R = 0 (the robot's own
  motion during a push was not logged; the displacement is the hand's); with
  ``--authors-updates``, one line per consecutive pair of logged poses instead, u_H = 3·Δ, as
  their learner updated. Empty and one-pose corrections give no update (nor did theirs); the
  episode line counts them.
- each record keeps the poses it spans as the authors logged them (their hand frame, roll′):
  ``authors_poses``, (n, 6), so a learner in their feature space (``strol-paper``) replays from
  the log alone.
- what the logs do not hold is marked, never invented: θ̂ before/after each correction (their
  learner aliased one buffer), start/end/correction times and forces (null), θ̂0 (the episode's
  ``theta_hat0`` is the Task prior's mean, or with ``--theta0 implied`` the θ̂0 worked back from
  the final θ̂ with the session's rule: ``theta_hat0_source`` says which). With ``--theta0
  implied`` each correction's ``theta_hat_before`` / ``theta_hat_after`` are reconstructed too
  (the implied θ̂0 and the same updates forward, in the authors' feature space; the header's
  ``extra["theta_hat"]`` says so). A StROL session's rule needs the authors' ĝ
  (``--authors-ghat GDIR``, :mod:`authors_ghat`; the header's ``extra["authors_ghat"]`` names
  its file and SHA-256); without it that session's θ̂ stays unknown (``NOT_RECONSTRUCTED``).
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.sessions.authors_frame import (
    FrameFit,
    fit_transform,
    logged_frame,
    pose_to_frame,
    rotation_angle,
)
from strol_gym.benchmarks.sessions.authors_ghat import FLAG, PAPER_LAMBDA, load_authors_ghat
from strol_gym.benchmarks.sessions.authors_rules import (
    AUTHORS_GAIN,
    PAPER,
    RULE_NAMES,
    RULES,
    reconstruct,
)
from strol_gym.benchmarks.sessions.plain_pickle import load_plain_pickle
from strol_gym.files import check_input
from strol_gym.provenance import package_versions
from strol_gym.tasks.study import STUDY_TASKS, StudyTask, wrap_angle
from strol_gym.wrappers.session_log import SessionWriter

ALGORITHMS = {"b1": "one", "b2": "mof", "ours": "strol"}
"""The authors' folder names and the learner each session ran."""
KEYS = ("theta_star", "theta_learned", "robot_traj", "corrections")
MAX_POSES = 1_000_000
"""The most poses one session may log (robot path plus corrections; the authors' ~2,000)."""
MAX_SESSIONS = 10_000
ENV_ID = "authors-user-study"
"""The ``env_id`` of an imported log: real sessions on the authors' Panda, not one of our envs."""
UNKNOWN = (
    "theta_hat per correction",
    "theta_hat0",
    "time and duration of each correction",
    "force",
    "u_R during a correction",
    "the order of the learners a participant met",
)
NOT_RECONSTRUCTED = {
    "ours": "not reconstructed: StROL's update adds the authors' trained ĝ term; give "
    f"{FLAG} GDIR (a checkout's user_study/g_data) to work θ̂0 and θ̂ per correction back",
}
"""Why ``--theta0 implied`` leaves θ̂ unknown in a session (written to its header)."""
_SESSION = re.compile(r"^user_(\d+)$")


@dataclasses.dataclass
class RawSession:
    """One checked authors' session (poses in their logged frame)."""

    path: Path
    user: int
    task: int
    alg: str
    theta_star: np.ndarray
    theta_final: np.ndarray | None
    """Their learner's θ̂ after the last correction (None without corrections)."""
    path_poses: np.ndarray
    """``robot_traj``: (n, 6), logged while no one pushed."""
    corrections: list[np.ndarray]
    """Per correction, (n_k, 6) logged poses (n_k may be 0)."""


def _array(where: str, value: Any, shape_tail: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a finite float64 array (n, *shape_tail), from an array or a list of rows;
    the count is checked before the rows are stacked."""
    if isinstance(value, np.ndarray):
        rows = value
        if rows.size == 0:
            return np.zeros((0, *shape_tail))
        if rows.shape[1:] != shape_tail:
            raise ValueError(f"{where}: {what} has shape {rows.shape}, want (n, {shape_tail})")
    elif isinstance(value, list):
        if len(value) > MAX_POSES:
            raise ValueError(f"{where}: {what} has {len(value)} rows (at most {MAX_POSES})")
        if not value:
            return np.zeros((0, *shape_tail))
        if not all(isinstance(r, np.ndarray) and r.shape == shape_tail for r in value):
            raise ValueError(f"{where}: {what} must be a list of arrays of shape {shape_tail}")
        rows = np.stack(value)
    else:
        raise ValueError(f"{where}: {what} must be an array or a list of arrays")
    if len(rows) > MAX_POSES:
        raise ValueError(f"{where}: {what} has {len(rows)} rows (at most {MAX_POSES})")
    out = np.asarray(rows, dtype=np.float64)
    if not np.isfinite(out).all():
        raise ValueError(f"{where}: {what} holds non-finite numbers")
    return out


def check_session(path: Path, data: Any, user: int, task: int, alg: str) -> RawSession:
    """The pickle's content checked against the authors' layout; ValueError names the file."""
    where = str(path)
    if not isinstance(data, dict) or not all(k in data for k in KEYS):
        raise ValueError(f"{where}: want a dict with keys {', '.join(KEYS)}")
    one = {}
    for k in KEYS:
        v = data[k]
        if not isinstance(v, list) or len(v) != 1:
            raise ValueError(f"{where}: {k!r} must be a one-element list (the session)")
        one[k] = v[0]
    d = STUDY_TASKS[task]().dim
    star = one["theta_star"]
    if not isinstance(star, np.ndarray) or star.shape != (d,) or not np.isfinite(star).all():
        raise ValueError(f"{where}: theta_star must be an array of {d} finite weights")
    corr_raw = one["corrections"]
    if not isinstance(corr_raw, list) or len(corr_raw) > MAX_POSES:
        raise ValueError(f"{where}: corrections must be a list (at most {MAX_POSES})")
    corrections = [_array(where, c, (6,), f"correction {i + 1}") for i, c in enumerate(corr_raw)]
    learned = _array(where, one["theta_learned"], (d,), "theta_learned")
    if len(learned) != len(corrections):
        raise ValueError(
            f"{where}: theta_learned has {len(learned)} entries, corrections {len(corrections)}"
        )
    path_poses = _array(where, one["robot_traj"], (6,), "robot_traj")
    if len(path_poses) == 0:
        raise ValueError(f"{where}: robot_traj is empty (the session's start is its first pose)")
    total = len(path_poses) + sum(len(c) for c in corrections)
    if total > MAX_POSES:
        raise ValueError(f"{where}: {total} poses (at most {MAX_POSES})")
    final = learned[-1] if len(learned) else None
    return RawSession(
        path, user, task, alg, star.astype(np.float64), final, path_poses, corrections
    )


def find_sessions(root: str | Path) -> list[tuple[Path, int, int, str]]:
    """(path, user, task, alg) of every ``user_K/task_J/ALG/data.pkl`` under ``root``."""
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"DIR {root}: not a folder (want a user_study/data tree)")
    found = []
    for user_dir in sorted(root.iterdir()):
        m = _SESSION.match(user_dir.name)
        if not m or not user_dir.is_dir():
            continue
        for task in (1, 2, 3):
            for alg in ALGORITHMS:
                p = user_dir / f"task_{task}" / alg / "data.pkl"
                if p.is_file():
                    found.append((p, int(m[1]), task, alg))
                elif os.path.lexists(p):  # a FIFO, a device, a dangling link: said, not skipped
                    check_input(p, "study file")
                if len(found) > MAX_SESSIONS:
                    raise ValueError(f"DIR {root}: more than {MAX_SESSIONS} sessions")
    if not found:
        raise ValueError(f"DIR {root}: no user_K/task_J/{{b1,b2,ours}}/data.pkl in it")
    found.sort(key=lambda f: (f[1], f[2], f[3]))
    return found


def read_sessions(root: str | Path) -> list[RawSession]:
    """Every session under ``root``, read with the plain-pickle reader and checked."""
    return [
        check_session(p, load_plain_pickle(p), user, task, alg)
        for p, user, task, alg in find_sessions(root)
    ]


def to_state(fit: FrameFit, poses: np.ndarray, task: StudyTask) -> np.ndarray:
    """Logged poses (n, 6) as the Task's states (cup position, and roll, pitch, yaw)."""
    cup = fit.to_cup(poses)
    return cup[..., :3] if not task.oriented else cup


def state_step(task: StudyTask, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """b − a in the Task's state (angles wrapped)."""
    d = np.asarray(b, dtype=np.float64) - a
    if task.oriented:
        d[..., 3:] = wrap_angle(d[..., 3:])
    return d


def _path_index(path_pos: np.ndarray, start: int, pos: np.ndarray) -> tuple[int, float]:
    """The robot-path sample (from ``start`` on) nearest ``pos``, and its distance (mm)."""
    dist = np.linalg.norm(path_pos[start:] - pos, axis=1)
    j = int(np.argmin(dist))
    return start + j, float(dist[j] * 1000.0)


def correction_lines(
    raw: RawSession,
    fit: FrameFit,
    task: StudyTask,
    authors_updates: bool,
    hats: list[np.ndarray] | None = None,
    theta0: np.ndarray | None = None,
) -> list[dict[str, Any]]:
    """The ``correction`` records of one session (see the module docstring); ``hats``, per
    correction θ̂ after each logged sample (``authors_rules.reconstruct``), and
    ``theta0`` fill θ̂ before/after each record where a One or MOF session's θ̂ is
    reconstructed (``--theta0 implied``)."""
    lines: list[dict[str, Any]] = []
    where = 0
    before = theta0 if hats is not None else None
    for k, poses in enumerate(raw.corrections):
        if len(poses) < 2:
            continue
        where, match_mm = _path_index(raw.path_poses[:, :3], where, poses[0, :3])
        states = to_state(fit, poses, task)
        frames = pose_to_frame(poses) @ fit.transform
        rot = math.degrees(float(rotation_angle(frames[0, :3, :3], frames[-1, :3, :3])))
        common = {
            "physical_correction": k,
            "samples": len(poses),
            "rotation_deg": rot,
            "path_sample": where,
            "path_samples": len(raw.path_poses),
            "path_match_mm": match_mm,
            "start_time": None,
            "end_time": None,
            "correction_time": None,
            "trace": None,
            "u_r_source": "unknown (0: u_H is the hand's whole logged displacement)",
        }
        steps: list[tuple[np.ndarray, np.ndarray, int | None]]
        if authors_updates:
            steps = [
                (states[i], AUTHORS_GAIN * state_step(task, states[i], states[i + 1]), i)
                for i in range(len(states) - 1)
            ]
        else:
            steps = [(states[0], state_step(task, states[0], states[-1]), None)]
        for i, (x, u_h, sample) in enumerate(steps):
            span = poses[i : i + 2] if authors_updates else poses
            after = None
            if hats is not None:
                after = hats[k][i] if authors_updates else hats[k][-1]
            rec = {
                "index": len(lines),
                "step": where,
                "x": x,
                "u_h": u_h,
                "u_r": np.zeros_like(u_h),
                "theta_hat_before": before,
                "theta_hat_after": after,
                "authors_poses": span,
                **common,
            }
            before = after
            if sample is not None:
                rec["sample"] = sample
            lines.append(rec)
    return lines


Implied = tuple[np.ndarray, list[np.ndarray]]
"""A session's implied θ̂0 and θ̂ after each logged sample (``authors_rules.reconstruct``)."""


def implied(raw: RawSession, ghat: str | Path | None) -> Implied | None:
    """The session's implied θ̂0 and θ̂ per sample under its own rule (None: no final θ̂, or a
    StROL session without the authors' ĝ)."""
    if raw.theta_final is None or (RULES[raw.alg] == PAPER and ghat is None):
        return None
    return reconstruct(raw.theta_final, raw.corrections, raw.task, RULES[raw.alg], ghat)


def write_session(
    raw: RawSession,
    out: Path,
    fit: FrameFit,
    authors_updates: bool,
    theta0: str,
    packages: dict[str, str | None] | None = None,
    rebuilt: Implied | None = None,
    ghat: str | Path | None = None,
) -> Path:
    """One authors' session as ``out/user_K_task_J_ALG.jsonl``; with ``theta0 == "implied"``
    its θ̂ is ``rebuilt`` (:func:`implied`) where the session's rule allows it."""
    task = STUDY_TASKS[raw.task]()
    from strol_gym.tasks import task_name

    path = out / f"user_{raw.user}_task_{raw.task}_{raw.alg}.jsonl"
    th0 = np.asarray(task.prior_modes, dtype=np.float64).mean(axis=0)
    source = "prior mean (θ̂0 was not logged)"
    hats, unknown = None, list(UNKNOWN)
    extra: dict[str, object] = {}
    if theta0 == "implied" and rebuilt is not None:
        rule = RULES[raw.alg]
        th0, hats = rebuilt
        source = f"implied: final θ̂ minus the authors' per-sample updates under {rule}"
        unknown = [u for u in unknown if u not in ("theta_hat per correction", "theta_hat0")]
        extra["theta_hat"] = (
            f"reconstructed: the implied θ̂0 and the authors' per-sample updates under {rule} "
            "in their feature space (authors_rules.reconstruct), not logged"
        )
        if rule == PAPER:
            extra["authors_ghat"] = load_authors_ghat(str(ghat), raw.task).describe()
    elif theta0 == "implied":
        source += " (this session's rule gives no implied θ̂0)"
        extra["theta_hat"] = NOT_RECONSTRUCTED.get(raw.alg, "not reconstructed: no final θ̂")
    header = {
        "created": None,
        "env_id": ENV_ID,
        "env_kwargs": {},
        "task": task_name(task),
        "task_describe": task.describe(),
        "learner": ALGORITHMS[raw.alg],
        "learner_kwargs": {},
        "packages": packages if packages is not None else package_versions(),
        "extra": {
            "source": "the authors' user study (VT-Collab/StROL_RAL, data removed at d383bef)",
            "user": raw.user,
            "study_task": raw.task,
            "authors_folder": raw.alg,
            "updates": "authors-per-sample (3·Δ)" if authors_updates else "one per correction",
            "frame": {
                "cup_offset_mm": fit.offset_mm,
                "turn_deg": fit.turn_deg,
                "residual_mm": fit.residual_mm,
            },
            "unknown": unknown,
            **extra,
        },
    }
    x0 = to_state(fit, raw.path_poses[0], task)
    sizes = [len(c) for c in raw.corrections]
    writer = SessionWriter(path, header)
    try:
        writer.episode(
            seed=None,
            theta_hat0=th0,
            theta_hat0_source=source,
            theta_star=raw.theta_star,
            x0=x0,
            theta_hat_final_logged=raw.theta_final,
            corrections_logged=len(raw.corrections),
            corrections_empty=sizes.count(0),
            corrections_one_pose=sizes.count(1),
            path_samples=len(raw.path_poses),
        )
        lines = correction_lines(raw, fit, task, authors_updates, hats, th0)
        for rec in lines:
            writer.correction(**rec)
        writer.end(
            reason="logged session",
            interrupted=False,
            steps=None,
            corrections=len(lines),
            theta_hat=None,
            error=None,
            cos_error=None,
            regret=None,
        )
    finally:
        writer.close()
    return path


def start_spread_mm(sessions: list[RawSession]) -> dict[int, np.ndarray]:
    """Per home (Task 1's, Task 2's), the distances (mm) of the logged starts from FK(home)."""
    out: dict[int, list[float]] = {1: [], 2: []}
    for s in sessions:
        home = 1 if s.task == 1 else 2
        fk = logged_frame(STUDY_TASKS[home]().home_q)[:3, 3]
        out[home].append(float(np.linalg.norm(s.path_poses[0, :3] - fk) * 1000.0))
    return {k: np.array(v) for k, v in out.items()}


def implied_lines(sessions: list[RawSession], rebuilt: dict[int, Implied]) -> list[str]:
    """Per folder whose rule was worked back: how many implied θ̂0 lie in the prior's box."""
    out = []
    for alg, rule in RULE_NAMES.items():
        mine = [i for i, s in enumerate(sessions) if s.alg == alg and s.theta_final is not None]
        if not mine or not all(i in rebuilt for i in mine):
            continue
        inside = sum(bool(np.all(np.abs(rebuilt[i][0]) <= 1.0)) for i in mine)
        out.append(f"implied θ̂0 inside [−1, 1]^d: {rule} {inside} of {len(mine)}")
    return out


def import_study(
    root: str | Path,
    out: str | Path,
    authors_updates: bool = False,
    theta0: str = "prior-mean",
    authors_ghat: str | Path | None = None,
) -> tuple[list[Path], FrameFit, dict[int, np.ndarray], list[str]]:
    """Read every session under ``root`` and write its log into ``out`` (which must not hold
    them already: logs are never overwritten). Also returns the implied-θ̂0 check's lines
    (``theta0 == "implied"``; StROL's with ``authors_ghat``, GDIR)."""
    if theta0 not in ("prior-mean", "implied"):
        raise ValueError(f"theta0 must be 'prior-mean' or 'implied', got {theta0!r}")
    if authors_ghat is not None:
        for number in (1, 2):  # both files read and checked before anything is written
            load_authors_ghat(authors_ghat, number)
    sessions = read_sessions(root)  # all checked before anything is written
    rebuilt: dict[int, Implied] = {}
    if theta0 == "implied":
        for i, s in enumerate(sessions):
            r = implied(s, authors_ghat)
            if r is not None:
                rebuilt[i] = r
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OSError(f"--out {out}: cannot create this folder ({e.strerror or e})") from None
    fit = fit_transform()
    packages = package_versions()
    written = []
    for i, s in enumerate(sessions):
        try:
            written.append(
                write_session(
                    s, out, fit, authors_updates, theta0, packages, rebuilt.get(i), authors_ghat
                )
            )
        except FileExistsError:
            raise ValueError(
                f"--out {out}: user_{s.user}_task_{s.task}_{s.alg}.jsonl exists (never overwritten)"
            ) from None
    return written, fit, start_spread_mm(sessions), implied_lines(sessions, rebuilt)


# ---------------------------------------------------------------------- CLI
def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "import-study",
        help="the authors' user-study pickles as session logs (replay them with replay)",
        description="Read a user_study/data tree (user_K/task_J/{b1,b2,ours}/data.pkl) with a "
        "reader that admits numeric numpy arrays, lists, dicts and numbers only, and write "
        "each session as a session log in the Study Task's cup frame. Each correction becomes "
        "one (x, u_H), u_H its first-to-last displacement; unknowns (θ̂ per correction, "
        "timing, θ̂0) are marked, not invented.",
    )
    p.add_argument("dir", help="the user_study/data folder")
    p.add_argument("--out", required=True, help="folder for the session logs (new files only)")
    p.add_argument(
        "--authors-updates",
        action="store_true",
        help="one update per consecutive pair of logged poses with u_H = 3·Δ (their learner)",
    )
    p.add_argument(
        "--theta0",
        choices=("prior-mean", "implied"),
        default="prior-mean",
        help="the episode's θ̂0: the Task prior's mean, or the θ̂0 implied by the final θ̂ "
        "under the session's own rule (with θ̂ before/after each correction; StROL sessions "
        f"need {FLAG})",
    )
    p.add_argument(
        FLAG,
        dest="authors_ghat",
        default=None,
        metavar="GDIR",
        help="a local checkout's user_study/g_data (model_t1, model_t2): the authors' ĝ, read "
        "with torch.load(weights_only=True), checked against their MLP, never copied",
    )


def command(args: Any, parser: Any) -> int:
    written, fit, spread, check = import_study(
        args.dir, args.out, args.authors_updates, args.theta0, args.authors_ghat
    )
    print(f"wrote {len(written)} session logs into {args.out}")
    if args.authors_ghat is not None:
        for number, tasks in ((1, "Task 1"), (2, "Tasks 2-3")):
            g = load_authors_ghat(args.authors_ghat, number)
            print(f"authors' ĝ for {tasks}: {g.path} sha256 {g.sha256} (λ = {PAPER_LAMBDA})")
    for line in check:
        print(line)
    print(
        f"frame: cup = logged frame · (offset {np.round(fit.offset_mm, 2).tolist()} mm, "
        f"turn {fit.turn_deg:.2f}° about z); residual at the homes "
        + ", ".join(
            f"Task {n}'s {fit.residual_mm[n]:.2f} mm / {fit.residual_deg[n]:.3f}°"
            for n in sorted(fit.residual_mm)
        )
        + "; fitted at one home only, the other's residual "
        + ", ".join(f"{fit.loo_mm[n]:.2f} mm" for n in sorted(fit.loo_mm))
    )
    for home, d in spread.items():
        if len(d):
            q = np.percentile(d, [0, 50, 100])
            print(
                f"logged starts vs FK(Task {home}'s home): {len(d)} sessions, "
                f"min {q[0]:.1f}, median {q[1]:.1f}, max {q[2]:.1f} mm"
            )
    return 0


__all__ = [
    "ALGORITHMS",
    "RawSession",
    "check_session",
    "find_sessions",
    "implied",
    "implied_lines",
    "import_study",
    "read_sessions",
    "write_session",
]
