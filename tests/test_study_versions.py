"""A StROL-Study version is said once (``strol_gym.envs.study.versions.VERSIONS``): its env id
and registration, its Task classes and their registry names, its ĝ's key (the Task's
``task_id``) and file names, and the benchmark's presets all derive from it, and nothing names
a version that is not in it. A sixth spelling (a literal env id, Task name, weights stem or
version name in code) fails ``test_no_code_spells_a_study_version``.
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import gymnasium as gym
import pytest

import strol_gym  # noqa: F401  (registers the envs)
from strol_gym.benchmarks.engine.conditions import ENV_PRESETS
from strol_gym.benchmarks.experiments.study import ENV_VERSIONS, study_env
from strol_gym.envs.study import env as study_env_module
from strol_gym.envs.study.versions import LATEST, VERSIONS, StudyVersion, version_of
from strol_gym.learners.checkpoint import PRETRAINED_DIR, find_pretrained
from strol_gym.tasks import TASKS, make_task
from strol_gym.tasks import study as study_tasks
from strol_gym.tasks.study import (
    STUDY_ENV,
    STUDY_TASK_SETS,
    StudyTask,
    study_task_id,
    study_task_name,
)

ROOT = Path(__file__).resolve().parent.parent
NUMBERS = (1, 2, 3)
VS = list(VERSIONS.values())


def test_the_version_set_names_itself():
    assert [v.name for v in VS] == list(VERSIONS) == list(ENV_VERSIONS)
    assert [v.number for v in VS] == sorted({v.number for v in VS})  # distinct, oldest first
    assert LATEST is VS[-1]
    assert all(version_of(v.env_id) is v for v in VS)
    with pytest.raises(ValueError, match="env_id"):
        version_of(f"{STUDY_ENV}-v99")


def test_registrations_are_the_versions():
    ids = {k for k in gym.registry if k.startswith(f"{STUDY_ENV}-")}
    assert ids == {v.env_id for v in VS}
    for v in VS:
        module, cls = gym.spec(v.env_id).entry_point.split(":")
        assert module == study_env_module.__name__ and cls == v.env_class
        env_cls = getattr(study_env_module, cls)
        assert env_cls.version is v and env_cls.env_id == v.env_id and env_cls.reach is v.reach
    # and no env class names a version outside the set
    classes = [c for c in vars(study_env_module).values() if isinstance(c, type)]
    named = {c.version for c in classes if issubclass(c, study_env_module.StudyEnv)}
    assert named == set(VS)


def test_tasks_are_the_versions():
    assert set(STUDY_TASK_SETS) == {v.number for v in VS}
    registered = {n for n in TASKS.names() if n.startswith("study-")}
    assert registered == {study_task_name(v.number, k) for v in VS for k in NUMBERS}
    for v in VS:
        assert sorted(v.tasks) == list(NUMBERS)
        assert sorted(v.numbered) == list(NUMBERS)
        for k, cls in v.tasks.items():
            assert (cls.version, cls.number) == (v.number, k)
            assert cls.task_id == study_task_id(v.number, k)
            assert cls.task_id.startswith(v.env_id + "-")
            assert type(make_task(study_task_name(v.number, k))) is cls
            assert type(make_task(cls.task_id)) is cls  # an env id finds it too
    # every Task class of the module is some version's, under the name the version gives it
    in_sets = {cls for tasks in STUDY_TASK_SETS.values() for cls in tasks.values()}
    pattern = re.compile(r"StudyTask(\d)(?:V(\d+))?")
    found = set()
    for name, obj in vars(study_tasks).items():
        m = pattern.fullmatch(name)
        if m and isinstance(obj, type) and issubclass(obj, StudyTask):
            assert (int(m[2] or 0), int(m[1])) == (obj.version, obj.number), name
            found.add(obj)
    assert found == in_sets


def _study_sidecars() -> dict[str, dict]:
    out = {}
    for side in sorted(PRETRAINED_DIR.glob("*.json")):
        meta = json.loads(side.read_text())
        if isinstance(meta, dict) and str(meta.get("task", {}).get("task_id", "")).startswith(
            f"{STUDY_ENV}-"
        ):
            out[side.stem] = meta
    return out


def test_ghat_keys_and_weight_names_are_the_versions():
    """Every shipped study ĝ is keyed by a version's Task and named by it; every version's
    every Task has its StROL and e2e ĝ."""
    tasks = {cls.task_id: cls for tasks in STUDY_TASK_SETS.values() for cls in tasks.values()}
    sidecars = _study_sidecars()
    assert sidecars
    for stem, meta in sidecars.items():
        cls = tasks[meta["task"]["task_id"]]
        assert meta["task"]["version"] == cls.version, stem
        assert stem == f"{cls.weights_stem}_{meta['kind']}"
        assert (PRETRAINED_DIR / f"{stem}.safetensors").is_file()
    for v in VS:
        for cls in v.tasks.values():
            for kind in ("strol", "e2e"):
                path = find_pretrained(cls(), kind)
                assert path.name == f"{cls.weights_stem}_{kind}.safetensors"


def test_presets_are_the_versions():
    """The study presets are exactly ``study_env``'s keys over the versions' Tasks (a version's
    people are a condition's person), each making its version's env and Task."""
    study = {k: p for k, p in ENV_PRESETS.items() if p.env_id.startswith(f"{STUDY_ENV}-")}
    derived = {}
    for v in VS:
        for k in NUMBERS:
            derived[study_env(k, v.name)] = (v, k)
    assert set(study) == set(derived)
    for key, (v, k) in derived.items():
        preset = study[key]
        assert preset.env_id == v.env_id, key
        task = (preset.make_kwargs or {})["task"]
        cls = type(make_task(task)) if isinstance(task, str) else v.numbered[task]
        assert cls is v.tasks[k], key


# ------------------------------------------------------------------------- no sixth spelling
SPELLING = re.compile(
    r"(StROL-Study-v\d+|study-task\d(-v\d+)?|study\d(-v\d+)?(_[\w-]+)?|v\d+|-v\d+)"
    r"|.*:Study(Env|Task\d)V\d+"
)
"""A whole string that is a study env id, Task name, weights stem or version name, a suffix
``-vN``, or an entry point naming a version's class."""
BUILDING = re.compile(r"StROL-Study-|(?<![\w-])study-task|(^|-)v$")
"""A piece of an f-string that builds one (``f"StROL-Study-{v}"``, ``f"...-v{n}"``)."""
CANDIDATE = re.compile(r"""StROL-Study-|study-task|study\d|["']v\d+["']|-v\d+["']|:Study|-v\{""")
"""What a file holding either must contain (a cheap filter before parsing it)."""
ALLOWED: dict[str, set[str]] = {
    # the one place: the naming functions, and the controller laws' names
    "strol_gym/tasks/study.py": {"-v", "study-task"},
    "strol_gym/envs/study/versions.py": {"v", "v0", "v1"},
    "strol_gym/envs/study/controller.py": {"v1"},
    # measured tables keyed by the published Tasks' registry names, as the fits wrote them
    "strol_gym/humans/aim.py": {"study-task1", "study-task2", "study-task3"},
    "strol_gym/humans/findings.py": {"study-task1", "study-task2", "study-task3"},
    # a Minari dataset's own version suffix, not the env's
    "benchmarks/serve/export.py": {"-v0"},
    # the presets, pinned to the versions by test_presets_are_the_versions
    "benchmarks/engine/conditions.py": {
        "StROL-Study-v0",
        "StROL-Study-v1",
        "StROL-Study-v2",
        "-v1",
        "-v2",
        "study-task",
    },
}


def _docstrings(tree: ast.AST) -> set[int]:
    """The ids of every string that is a statement of its own (docstrings, attribute notes)."""
    out = set()
    for node in ast.walk(tree):
        for field in ("body", "orelse", "finalbody"):
            body = getattr(node, field, None)
            if isinstance(body, list):
                out |= {
                    id(s.value)
                    for s in body
                    if isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant)
                }
    return out


def _spellings(tree: ast.AST) -> list[tuple[int, str]]:
    skip = _docstrings(tree)
    pieces = set()
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            for part in node.values:
                if isinstance(part, ast.Constant) and isinstance(part.value, str):
                    pieces.add(id(part))
                    if BUILDING.search(part.value):
                        out.append((node.lineno, part.value))
        elif (
            isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in skip
        ):
            if id(node) not in pieces and SPELLING.fullmatch(node.value):
                out.append((node.lineno, node.value))
    return out


def test_no_code_spells_a_study_version():
    found = []
    for top in ("strol_gym", "benchmarks"):
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            text = path.read_text(encoding="utf-8")
            if not CANDIDATE.search(text):
                continue
            for line, value in _spellings(ast.parse(text)):
                if value not in ALLOWED.get(rel, set()):
                    found.append(f"{rel}:{line}: {value!r}")
    assert not found, "derive these from strol_gym.envs.study.versions:\n" + "\n".join(found)


def test_a_new_version_is_a_new_option_set():
    """What a further version needs from the set: its names follow from its number."""
    v9 = StudyVersion(9)
    assert (v9.name, v9.env_id, v9.env_class) == ("v9", f"{STUDY_ENV}-v9", "StudyEnvV9")
    assert study_task_name(9, 2) == "study-task2-v9"
    assert study_task_id(9, 2) == f"{STUDY_ENV}-v9-task2"


def test_a_task_that_names_itself_keeps_its_name():
    """A Task built on a study Task with its own ``task_id`` (another setting) keeps it and
    gets no study weights stem; one without takes the study's names."""
    own = type("Own", (study_tasks.StudyTask2,), {"task_id": "own-task", "__module__": __name__})
    assert (own.task_id, own.weights_stem) == ("own-task", None)
    plain = type("Plain", (study_tasks.StudyTask2V1,), {"__module__": __name__})
    assert (plain.task_id, plain.weights_stem) == (study_task_id(1, 2), "study2-v1")
