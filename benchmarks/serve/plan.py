"""A study as a researcher writes it (``strol-bench serve --study PLAN``) and who does what.

The plan is a JSON object (every field optional but ``name``)::

    {"name": "pilot", "consent": "consent.txt", "learners": ["one", "mof", "strol"],
     "tasks": [1, 2, 3], "highway": true, "duration": 60, "practice": 20, "seed": 0}

``consent`` is a plain-text file beside the plan, shown before anything starts (the page shows
it as text, never as HTML). ``learners`` are registered learner names (never ``module:attr``:
a plan names no code); ``tasks`` the study's Tasks. Each participant gets an anonymous id and a
counterbalanced order: the learners' order is row ``k mod L`` of a cyclic Latin square (as the
paper's study), the Tasks' order row ``(k div L) mod T`` of another, ``k`` the participant's
number in arrival order, so L × T participants see every pair of orders once. Every participant
first does a short practice on the arm (Task 1) and, with ``highway``, on the car; then, per
learner, each Task on the arm, then the car. A learner is shown as "robot A, B, ..." by its
place in the participant's order, never by name.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
import secrets
import threading
from pathlib import Path
from typing import Any

from strol_gym.files import loads_json, read_regular, write_json_atomic

NAME = re.compile(r"^[a-z0-9][a-z0-9_-]{0,39}$")
"""A study's name: it names the Minari datasets (``NAME/arm-task1-strol-v0``)."""
MAX_PLAN_BYTES = 64_000
MAX_CONSENT_BYTES = 64_000
DURATION_RANGE = (5.0, 600.0)
"""Simulated seconds a session (or a practice) may last."""
PRACTICE_LEARNER = "strol"
"""The learner of the practice sessions (they are logged, never exported)."""
DEFAULT_CONSENT = (
    "This is a practice of the StROL study interface: push the robot arm's cup and correct a "
    "car from your keyboard or gamepad. Nothing identifies you: your pushes are logged under "
    "an anonymous id on the computer that runs this page."
)


@dataclasses.dataclass(frozen=True)
class StudyPlan:
    name: str = "practice"
    consent: str = DEFAULT_CONSENT
    learners: tuple[str, ...] = ()
    tasks: tuple[int, ...] = (1, 2, 3)
    highway: bool = True
    duration: float = 60.0
    practice: float = 20.0
    seed: int = 0

    @property
    def digest(self) -> str:
        """What identifies the plan in the participants' file (a restart must not mix plans)."""
        text = repr(dataclasses.astuple(self)).encode()
        return hashlib.sha256(text).hexdigest()[:16]


def _number(what: str, value: Any, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{what} must be a number in [{low:g}, {high:g}], got {value!r:.40}")
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"{what} must be in [{low:g}, {high:g}], got {value!r}")
    return float(value)


def load_plan(path: str | Path | None) -> StudyPlan:
    """The plan at ``path`` (None: practice only, one session each on the arm and the car),
    checked field by field; a ValueError names the field and what it accepts."""
    from strol_gym.learners.registry import LEARNERS

    if path is None:
        return StudyPlan()
    path = Path(path)
    where = f"--study {path}"
    data = read_regular(path, MAX_PLAN_BYTES, "--study")  # a regular file (a FIFO would block)
    raw = loads_json(data, where)
    if not isinstance(raw, dict):
        raise ValueError(f"{where}: a plan is a JSON object")
    known = {f.name for f in dataclasses.fields(StudyPlan)}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise ValueError(f"{where}: unknown field(s) {unknown}; known: {sorted(known)}")
    name = raw.get("name")
    if not isinstance(name, str) or not NAME.match(name):
        raise ValueError(f"{where}: 'name' must match {NAME.pattern} (it names the datasets)")
    consent = DEFAULT_CONSENT
    if "consent" in raw:
        file = raw["consent"]
        if not isinstance(file, str) or not file or Path(file).is_absolute() or ".." in file:
            raise ValueError(f"{where}: 'consent' must be a file name beside the plan")
        text = read_regular(path.parent / file, MAX_CONSENT_BYTES, f"{where}: the consent text")
        consent = text.decode("utf-8", errors="replace")
    learners = raw.get("learners", ["one", "mof", "strol"])
    names = LEARNERS.names()
    if (
        not isinstance(learners, list)
        or not 1 <= len(learners) <= 8
        or len(set(map(str, learners))) != len(learners)
        or not all(isinstance(n, str) and n in names for n in learners)
    ):
        raise ValueError(f"{where}: 'learners' must be 1-8 distinct names of {names}")
    tasks = raw.get("tasks", [1, 2, 3])
    if (
        not isinstance(tasks, list)
        or not 1 <= len(tasks) <= 3
        or len(set(map(str, tasks))) != len(tasks)
        or not all(t in (1, 2, 3) and not isinstance(t, bool) for t in tasks)
    ):
        raise ValueError(f"{where}: 'tasks' must be distinct Tasks of 1, 2, 3")
    highway = raw.get("highway", True)
    if not isinstance(highway, bool):
        raise ValueError(f"{where}: 'highway' must be true or false")
    seed = raw.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**31:
        raise ValueError(f"{where}: 'seed' must be an integer in [0, 2**31)")
    return StudyPlan(
        name=name,
        consent=consent,
        learners=tuple(learners),
        tasks=tuple(tasks),
        highway=highway,
        duration=_number(f"{where}: 'duration'", raw.get("duration", 60.0), *DURATION_RANGE),
        practice=_number(f"{where}: 'practice'", raw.get("practice", 20.0), *DURATION_RANGE),
        seed=seed,
    )


def latin_row(items: tuple[Any, ...], row: int) -> tuple[Any, ...]:
    """Row ``row`` of the cyclic Latin square of ``items``: each item once per row and once
    per place over ``len(items)`` rows."""
    n = len(items)
    return tuple(items[(row + i) % n] for i in range(n))


@dataclasses.dataclass(frozen=True)
class SessionSpec:
    """One session a participant runs: what the worker builds (no path: the server names it)."""

    kind: str  # "arm" or "car"
    label: str
    learner: str
    task: int  # the arm's Task (the car: 0)
    duration: float
    seed: int
    practice: bool

    def log_name(self, index: int) -> str:
        where = f"task{self.task}" if self.kind == "arm" else "highway"
        what = "practice" if self.practice else self.learner
        return f"{index:02d}-{self.kind}-{where}-{what}.jsonl"


def schedule(plan: StudyPlan, k: int) -> tuple[dict[str, Any], list[SessionSpec]]:
    """Participant number ``k``'s orders and sessions (module docstring)."""
    seed = plan.seed + 1000 * k
    out = [SessionSpec("arm", "Practice: the arm", PRACTICE_LEARNER, 1, plan.practice, seed, True)]
    if plan.highway:
        out.append(
            SessionSpec("car", "Practice: the car", PRACTICE_LEARNER, 0, plan.practice, seed, True)
        )
    if not plan.learners:  # no plan: the practice is all
        return {"learners": [], "tasks": []}, out
    learners = latin_row(plan.learners, k % len(plan.learners))
    tasks = latin_row(plan.tasks, (k // len(plan.learners)) % len(plan.tasks))
    for i, learner in enumerate(learners):
        robot = f"robot {chr(ord('A') + i)}"
        for task in tasks:
            out.append(
                SessionSpec(
                    "arm", f"Task {task} with {robot}", learner, task, plan.duration, seed, False
                )
            )
            seed += 1
        if plan.highway:
            out.append(
                SessionSpec("car", f"The car with {robot}", learner, 0, plan.duration, seed, False)
            )
            seed += 1
    return {"learners": list(learners), "tasks": list(tasks)}, out


class Participants:
    """Who came, in arrival order, kept in ``out/participants.json`` (written all or nothing
    at every change, so a restart continues the counterbalancing and loses nobody)."""

    FILE = "participants.json"

    def __init__(self, out: Path, plan: StudyPlan) -> None:
        self.out, self.plan = Path(out), plan
        self.out.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self.path = self.out / self.FILE
        self.state: dict[str, Any] = {"plan": plan.digest, "name": plan.name, "participants": {}}
        if self.path.exists():
            state = loads_json(read_regular(self.path), str(self.path))
            if not isinstance(state, dict) or not isinstance(state.get("participants"), dict):
                raise ValueError(f"{self.path}: not a participants file of strol-bench serve")
            if state.get("plan") != plan.digest:
                raise ValueError(
                    f"--out {self.out} holds a study run with another plan ({state.get('name')}):"
                    " give a new --out for a new plan"
                )
            self.state = state

    def join(self) -> tuple[str, int, list[SessionSpec]]:
        """A new participant: an anonymous id, their number and their sessions."""
        with self._lock:
            people = self.state["participants"]
            k = len(people)
            pid = "p" + secrets.token_hex(4)
            while pid in people:
                pid = "p" + secrets.token_hex(4)
            orders, sessions = schedule(self.plan, k)
            people[pid] = {"number": k, **orders, "sessions": []}
            self._save()
        return pid, k, sessions

    def preview(self) -> tuple[dict[str, Any], list[SessionSpec]]:
        """The next participant's orders and sessions (nobody joins)."""
        with self._lock:
            return schedule(self.plan, len(self.state["participants"]))

    def record(self, pid: str, spec: SessionSpec, log: str, reason: str, corrections: int) -> None:
        """A session ended (``log``: its path under ``out``)."""
        with self._lock:
            entry = {
                "log": log,
                "reason": reason,
                "corrections": corrections,
                **dataclasses.asdict(spec),
            }
            self.state["participants"][pid]["sessions"].append(entry)
            self._save()

    def _save(self) -> None:
        write_json_atomic(self.path, self.state)


__all__ = ["Participants", "SessionSpec", "StudyPlan", "latin_row", "load_plan", "schedule"]
