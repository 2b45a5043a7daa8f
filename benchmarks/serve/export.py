"""A study served by ``strol-bench serve`` as Minari datasets (``serve --export``).

One dataset holds one env, Task and learner (Minari's spaces are a dataset's), so a study is a
Minari *namespace*, the plan's name, with one dataset per arm Task and learner
(``NAME/arm-task1-strol-v0``) and per learner on the car (``NAME/car-strol-v0``); each holds
every participant's session of that kind, in arrival order. Practice sessions are left out, and
so is a session whose log cannot be read (a process that died before its header).
"""

from __future__ import annotations

from pathlib import Path

from strol_gym.benchmarks.serve.plan import Participants, StudyPlan
from strol_gym.wrappers.session_log import SessionLogError, read_session


def study_logs(out: Path, plan: StudyPlan) -> dict[str, list[Path]]:
    """Dataset id -> the study's readable, non-practice logs for it, in arrival order."""
    people = Participants(out, plan).state["participants"]
    groups: dict[str, list[Path]] = {}
    for person in sorted(people.values(), key=lambda p: p["number"]):
        for s in person["sessions"]:
            if s["practice"]:
                continue
            log = Path(out) / s["log"]
            try:
                read_session(log)
            except (SessionLogError, OSError):
                continue
            what = f"arm-task{s['task']}" if s["kind"] == "arm" else "car"
            groups.setdefault(f"{plan.name}/{what}-{s['learner']}-v0", []).append(log)
    return groups


def export_study(out: Path, plan: StudyPlan) -> list[tuple[str, int]]:
    """Write every dataset of the study in ``out``; (dataset id, sessions) per dataset."""
    from strol_gym.benchmarks.sessions.export import export_session

    groups = study_logs(out, plan)
    if not groups:
        raise ValueError(f"--out {out}: no completed study session to export (practice aside)")
    done = []
    for dataset_id, logs in sorted(groups.items()):
        export_session(list(logs), dataset_id)
        done.append((dataset_id, len(logs)))
    return done


__all__ = ["export_study", "study_logs"]
