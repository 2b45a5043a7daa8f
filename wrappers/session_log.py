"""Session logs: every correction a learner saw, written as it happens, reusable as data.

Format (JSON Lines, UTF-8, one object per line, ``"type"`` says which):

- ``header`` (line 1): ``format`` = "strol-session", ``version`` = 1, ``created`` (UTC ISO
  time), ``env_id``, ``env_kwargs``, ``task`` (a registered Task name, or the "module:attr" of a
  Task of a plugin; :func:`session_task` looks it up and never imports what a log names),
  ``task_describe`` (``Task.describe()``),
  ``learner`` and ``learner_kwargs``, ``packages`` (versions), ``extra`` (anything the front end
  adds, e.g. the interactive mode's options).
- ``episode``: ``seed``, ``theta_hat0`` (where the learner started), ``theta_star`` (the
  preference the person was asked to teach, or null), ``x0``.
- ``correction``: ``index`` (0, 1, ... within the episode), ``x`` (the state where it began),
  ``u_h``, ``u_r``, ``theta_hat_before``, ``theta_hat_after``, ``start_time``, ``end_time``,
  ``correction_time`` (s; null for envs whose corrections are single steps), ``step``, and
  ``trace`` = {``t``, ``force``, ``torque``} (the external wrench per control step; null when
  the env reports none).
- ``event`` (optional, any number): ``kind`` (e.g. "reflex": a push above the arm's force
  reflex, which braked it and made no correction), ``time``, ``step``, and what the kind
  carries (a reflex: ``force``, ``torque``, ``reflex_force``). Readers of corrections skip them.
- ``end`` (optional): ``steps``, ``corrections``, ``theta_hat``, ``error``, ``cos_error``,
  ``regret``, ``reason``, ``interrupted`` (true when the person stopped it with Ctrl-C),
  ``sim_time`` (simulated seconds, or null where the env reports no ``info["time"]``), and
  anything a front end adds (a person session: ``reflexes``).

Each line is flushed and fsynced when written, so a crash loses at most the correction under
way. :func:`read_session` validates a file and names the file and line of the first bad one.

This module owns the format: the writer, the reader and :func:`check_header`. Converters to
other formats (``benchmarks/sessions/export.py``, Minari) validate through these, never their own.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np

from strol_gym.files import open_regular
from strol_gym.learners.protocol import OnlineRewardLearner
from strol_gym.limits import CAPS, lifted_now
from strol_gym.provenance import package_versions
from strol_gym.registry import registered_name, spec_of
from strol_gym.tasks import Task, task_name
from strol_gym.tasks.base import _jsonable
from strol_gym.wrappers.online_learning import learning_env

FORMAT, VERSION = "strol-session", 1


def _json(value: Any) -> Any:
    """JSON-ready: arrays as lists, numpy scalars as numbers, non-finite floats as null."""
    value = _jsonable(value)
    if isinstance(value, dict):
        return {str(k): _json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return registered_name(value) or spec_of(value) or repr(value)


class SessionWriter:
    """Append-only writer of one session log (see the module docstring for the format)."""

    def __init__(self, path: str | Path, header: dict[str, Any]) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.path.open("x", encoding="utf-8")  # never overwrite a session
        self._line("header", {"format": FORMAT, "version": VERSION, **header})

    def _line(self, kind: str, record: dict[str, Any]) -> None:
        self._file.write(json.dumps({"type": kind, **_json(record)}, allow_nan=False) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())

    def episode(self, **record: Any) -> None:
        self._line("episode", record)

    def correction(self, **record: Any) -> None:
        self._line("correction", record)

    def event(self, **record: Any) -> None:
        """Something the person did that is no correction (``kind``, e.g. "reflex": a push
        above the arm's reflex, with its ``force``), at ``time``."""
        self._line("event", record)

    def end(self, **record: Any) -> None:
        self._line("end", record)

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()


@runtime_checkable
class _Learning(Protocol):
    """A wrapper that holds a learner (an OnlineLearningWrapper, or a wrapper reading its)."""

    @property
    def learner(self) -> OnlineRewardLearner: ...


def _unwrap_learning(env: gym.Env) -> _Learning:
    """The OnlineLearningWrapper in ``env``'s stack (it owns the learner)."""
    e = env
    while isinstance(e, gym.Wrapper):
        if isinstance(e, _Learning):  # it has .learner
            return e
        e = e.env
    raise ValueError("env must be wrapped in OnlineLearningWrapper (it holds the learner)")


class SessionLogger(gym.Wrapper):
    """Log every correction of an ``OnlineLearningWrapper``-wrapped env to a session file.

    x, u_H and u_R are what the wrapper gave its learner (contract: x =
    ``info["correction_state"]`` if present, else the previous observation's state; u_H =
    ``obs["correction"]``; u_R = ``info["robot_action"]``), so any strol-gym env's session can
    be replayed. A multi-step correction's ``info["correction_record"]`` adds the wrench trace.
    """

    def __init__(
        self,
        env: gym.Env,
        path: str | Path,
        extra: dict[str, Any] | None = None,
        auto_end: bool = True,
    ) -> None:
        """``auto_end`` false: an episode's end writes no ``end`` line; the front end writes it
        with its own reason (``end_session``)."""
        super().__init__(env)
        self.auto_end = auto_end
        learning = _unwrap_learning(env)
        saved = getattr(learning, "_saved_kwargs", {})
        learner = saved.get("learner", learning.learner)
        spec = env.unwrapped.spec
        task = learning_env(env).task
        header = {
            "created": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "env_id": spec.id if spec is not None else type(env.unwrapped).__name__,
            "env_kwargs": dict(spec.kwargs) if spec is not None else {},
            "task": task_name(task),
            "task_describe": task.describe(),
            "learner": learner
            if isinstance(learner, str)
            else registered_name(learner) or spec_of(learner),
            "learner_kwargs": saved.get("learner_kwargs") or {},
            "packages": package_versions(),
            "extra": extra or {},
        }
        self.writer = SessionWriter(path, header)
        self._learning = learning
        self._x: np.ndarray | None = None
        self._index = 0
        self._steps = 0

    @property
    def learner(self) -> Any:
        """The wrapped OnlineLearningWrapper's learner (what the benchmark's loop reads)."""
        return self._learning.learner

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._x = np.asarray(obs["state"], dtype=np.float64).copy()
        self._index = 0
        self._steps = 0
        theta_star = info.get("theta_star")
        self.writer.episode(
            seed=seed,
            theta_hat0=info["theta_hat"],
            theta_star=theta_star,
            x0=self._x,
        )
        return obs, info

    def step(self, action):
        before = np.asarray(self._learning.learner.theta, dtype=np.float64).copy()
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        if info.get("is_correction", False):
            x = info.get("correction_state")
            rec = info.get("correction_record") or {}
            trace = None
            if "times" in rec:
                trace = {"t": rec["times"], "force": rec["force"], "torque": rec["torque"]}
            start, end = rec.get("start_time"), rec.get("end_time")
            self.writer.correction(
                index=self._index,
                step=self._steps,
                x=self._x if x is None else x,
                u_h=obs["correction"],
                u_r=info["robot_action"],
                theta_hat_before=before,
                theta_hat_after=info["theta_hat"],
                start_time=start,
                end_time=end,
                correction_time=None if start is None or end is None else float(end) - float(start),
                trace=trace,
            )
            self._index += 1
        self._x = np.asarray(obs["state"], dtype=np.float64).copy()
        if (terminated or truncated) and self.auto_end:
            self.end_session("truncated" if truncated else "terminated", info)
        return obs, reward, terminated, truncated, info

    def end_session(
        self,
        reason: str,
        info: dict[str, Any] | None = None,
        interrupted: bool = False,
        **extra: Any,
    ) -> None:
        """Write the ``end`` line (once per episode end, or when a front end stops early;
        ``interrupted``: the person stopped it with Ctrl-C; ``extra``: more fields)."""
        info = info or {}
        self.writer.end(
            reason=reason,
            interrupted=interrupted,
            steps=self._steps,
            corrections=self._index,
            theta_hat=np.asarray(self._learning.learner.theta, dtype=np.float64),
            error=info.get("error"),
            cos_error=info.get("cos_error"),
            regret=info.get("regret"),
            sim_time=info.get("time"),
            **extra,
        )

    def close(self) -> None:
        self.writer.close()
        super().close()


# ---------------------------------------------------------------------- reading
@dataclasses.dataclass
class Episode:
    seed: int | None
    theta_hat0: np.ndarray
    theta_star: np.ndarray | None
    corrections: list[dict[str, Any]]


@dataclasses.dataclass
class Session:
    path: Path
    header: dict[str, Any]
    episodes: list[Episode]

    @property
    def n_corrections(self) -> int:
        return sum(len(e.corrections) for e in self.episodes)


class SessionLogError(ValueError):
    """A session log that cannot be read; the message names the file and line."""


def _vector(where: str, rec: dict, key: str, dim: int | None, optional: bool = False):
    value = rec.get(key)
    if value is None and optional:
        return None
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        arr = np.array([np.nan])
    if arr.ndim != 1 or (dim is not None and arr.shape[0] != dim) or not np.isfinite(arr).all():
        size = f"{dim} " if dim is not None else ""
        raise SessionLogError(f"{where}: {key!r} must be a list of {size}finite numbers")
    return arr


def _poses(where: str, value: Any) -> np.ndarray:
    """``authors_poses``: (n, 6) finite numbers, n ≥ 2 (the line's size is capped already)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        arr = np.array([np.nan])
    if arr.ndim != 2 or arr.shape[1] != 6 or len(arr) < 2 or not np.isfinite(arr).all():
        raise SessionLogError(f"{where}: 'authors_poses' must be a list of >= 2 rows of 6 numbers")
    return arr


def _dimension(where: str, desc: dict, key: str) -> int:
    value = desc.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 < value <= 10_000:
        raise SessionLogError(f"{where}: 'task_describe' needs {key!r} (an integer in [1, 10000])")
    return value


def check_header(where: str, rec: dict) -> tuple[dict[str, Any], dict[str, int]]:
    """Check line 1 (types only: resolving the Task is the reader's business, never an import)."""
    if rec.get("type") != "header" or rec.get("format") != FORMAT:
        raise SessionLogError(f"{where}: not a {FORMAT} log (line 1 must be its header)")
    if rec.get("version") != VERSION:
        raise SessionLogError(f"{where}: version {rec.get('version')!r}, want {VERSION}")
    for key in ("task", "env_id"):
        if not isinstance(rec.get(key), str) or not rec[key]:
            raise SessionLogError(f"{where}: the header needs {key!r} (a name)")
    if rec.get("learner") is not None and not isinstance(rec["learner"], str):
        raise SessionLogError(f"{where}: the header's 'learner' must be a name")
    desc = rec.get("task_describe")
    if not isinstance(desc, dict):
        raise SessionLogError(f"{where}: 'task_describe' must be an object (Task.describe())")
    names = desc.get("feature_names")
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise SessionLogError(f"{where}: 'task_describe' needs 'feature_names' (a list of names)")
    dims = {"d": len(names), "s": _dimension(where, desc, "state_dim")}
    dims["a"] = _dimension(where, desc, "action_dim")
    return rec, dims


def _parse(where: str, text: str) -> Any:
    """One line's JSON; every failure (deep nesting, huge integers...) names file:line."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise SessionLogError(f"{where}: not JSON ({e.msg})") from None
    except RecursionError:
        raise SessionLogError(f"{where}: not a session log line (nested too deeply)") from None
    except ValueError as e:  # e.g. an integer beyond Python's digit limit
        raise SessionLogError(f"{where}: not a session log line ({e})") from None


def _lines(path: Path) -> Iterator[tuple[int, bytes]]:
    """(line number, bytes) of a log, each line read with a bounded ``readline``: a line over
    the cap (``strol_gym.limits``, ``session_line_bytes``) is refused before it is held whole."""
    cap = CAPS["session_line_bytes"] if not lifted_now() else None
    try:
        with open_regular(path, "session log") as f:
            no = 0
            while True:
                line = f.readline(-1 if cap is None else cap + 1)
                if not line:
                    return
                no += 1
                if cap is not None and len(line) > cap and not line.endswith(b"\n"):
                    raise SessionLogError(
                        f"{path}:{no}: a line longer than {cap:,} bytes (the cap on a session "
                        "log line; strol_gym.limits.lift() lifts it)"
                    )
                yield no, line.rstrip(b"\n")
    except OSError as e:
        raise SessionLogError(f"{path}: cannot read the session log ({e})") from e


def read_session(path: str | Path) -> Session:
    """Parse and validate a session log; :class:`SessionLogError` names the file and line.

    Reading runs no code: the header's Task is a name, looked up by :func:`session_task`.
    """
    path = Path(path)
    header: dict[str, Any] | None = None
    episodes: list[Episode] = []
    dims: dict[str, int] = {}
    for no, line in _lines(path):
        where = f"{path}:{no}"
        try:
            text = line.decode("utf-8")
        except UnicodeDecodeError:
            raise SessionLogError(f"{where}: not UTF-8 text (not a session log line)") from None
        if not text.strip():
            continue
        rec = _parse(where, text)
        if not isinstance(rec, dict):
            raise SessionLogError(f"{where}: a session log line must be a JSON object")
        kind = rec.get("type")
        if header is None:
            header, dims = check_header(where, rec)
        elif kind == "episode":
            theta0 = _vector(where, rec, "theta_hat0", dims["d"])
            star = _vector(where, rec, "theta_star", dims["d"], optional=True)
            seed = rec.get("seed")
            if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
                raise SessionLogError(f"{where}: 'seed' must be an integer or null")
            episodes.append(Episode(seed, theta0, star, []))
        elif kind == "correction":
            if not episodes:
                raise SessionLogError(f"{where}: a correction before any 'episode' line")
            ctime = rec.get("correction_time")
            if ctime is not None and (
                isinstance(ctime, bool) or not isinstance(ctime, int | float)
            ):
                raise SessionLogError(f"{where}: 'correction_time' must be a number or null")
            c = {
                "x": _vector(where, rec, "x", dims["s"]),
                "u_h": _vector(where, rec, "u_h", dims["a"]),
                "u_r": _vector(where, rec, "u_r", dims["a"]),
                "theta_hat_after": _vector(where, rec, "theta_hat_after", dims["d"], True),
                "theta_hat_before": _vector(where, rec, "theta_hat_before", dims["d"], True),
                "correction_time": ctime,
            }
            if rec.get("authors_poses") is not None:  # import-study: the logged poses it spans
                c["authors_poses"] = _poses(where, rec["authors_poses"])
            episodes[-1].corrections.append(c)
        elif kind == "header":
            raise SessionLogError(f"{where}: a second header")
        elif kind == "event":
            if not isinstance(rec.get("kind"), str):
                raise SessionLogError(f"{where}: an 'event' line needs a string 'kind'")
        elif kind != "end":
            raise SessionLogError(f"{where}: unknown line type {kind!r}")
    if header is None:
        raise SessionLogError(f"{path}: empty session log")
    if not episodes:
        raise SessionLogError(f"{path}: no 'episode' line")
    return Session(path, header, episodes)


LEGACY_TASKS: dict[str, str] = {
    "strol_gym.tasks.robot:RobotTask": "robot",
    "strol_gym.tasks.highway:HighwayTask": "highway",
    "strol_gym.tasks.study:StudyTask1": "study-task1",
    "strol_gym.tasks.study:StudyTask2": "study-task2",
    "strol_gym.tasks.study:StudyTask3": "study-task3",
    "strol_gym.tasks.study:StudyTask1V1": "study-task1-v1",
    "strol_gym.tasks.study:StudyTask2V1": "study-task2-v1",
    "strol_gym.tasks.study:StudyTask3V1": "study-task3-v1",
}
"""Module paths older headers named strol-gym's own Tasks by -> their registered names. Fixed:
headers now name registered pieces, and these paths are never imported (code moves)."""


def session_task(session: Session) -> Task:
    """The header's Task: a registered name (an old header's module path of one of ours is read
    through :data:`LEGACY_TASKS`), or a ``module:attr`` in a module the user loaded with
    ``--plugin`` (never imported from the log); it must match the logged dimensions."""
    from strol_gym.registry import resolve_logged
    from strol_gym.tasks import make_task

    where = f"{session.path}:1"
    name = session.header["task"]
    name = LEGACY_TASKS.get(name, name)
    try:
        task = make_task(resolve_logged("task", name))
    except ValueError as e:
        raise SessionLogError(f"{where}: {e}") from None
    desc = session.header["task_describe"]
    logged = (len(desc["feature_names"]), desc["state_dim"], desc["action_dim"])
    if (task.dim, task.state_dim, task.action_dim) != logged:
        raise SessionLogError(
            f"{where}: task {name!r} has (features, state, action) dimensions "
            f"{(task.dim, task.state_dim, task.action_dim)}, the log {logged}"
        )
    return task


__all__ = [
    "LEGACY_TASKS",
    "Episode",
    "Session",
    "SessionLogError",
    "SessionLogger",
    "SessionWriter",
    "read_session",
    "session_task",
    "task_name",
]
