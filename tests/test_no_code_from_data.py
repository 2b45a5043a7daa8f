"""No code from data: every reader of a file this project reads (session logs, Minari datasets,
results folders with their plugin lists, checkpoints and sidecars, the experiments' CSV/JSON)
is fed a file naming code (``os:system`` with a command that writes a marker file,
``builtins:eval``, a module whose import writes the marker) at every place a name can appear,
and the marker never appears. Dataset ids are confined to the datasets root; headers name
registered pieces and our own Study-v1 exports replay."""

from __future__ import annotations

import csv
import json
import shutil
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from cli_checks import cli_error
from test_minari import cli, robot_session

from strol_gym.benchmarks.cli import main
from strol_gym.benchmarks.sessions.dataset_gate import check_env_spec, wrappers
from strol_gym.benchmarks.sessions.export import read_any
from strol_gym.benchmarks.sessions.replay import replay_session
from strol_gym.learners.checkpoint import rehash_sidecar, save_checkpoint
from strol_gym.learners.network import CorrectionNet
from strol_gym.learners.registry import make_learner
from strol_gym.registration import ENV_SPECS
from strol_gym.tasks import make_task
from strol_gym.wrappers import OnlineLearningWrapper
from strol_gym.wrappers.session_log import LEGACY_TASKS, SessionLogger, read_session

minari = pytest.importorskip("minari", reason='Minari is not installed (pip install ".[data]")')

SIDE_EFFECT = "sideeffect_ncfd"
"""A module the test writes whose import writes the marker (a name no other test uses)."""


@pytest.fixture
def marker(tmp_path, monkeypatch) -> Path:
    """The marker file; the side-effect module importable from tmp_path (its import, or any
    ``os:system`` call with the test's command, creates the marker)."""
    path = tmp_path / "PWNED"
    (tmp_path / f"{SIDE_EFFECT}.py").write_text(
        f"from pathlib import Path\nPath({str(path)!r}).write_text('imported')\n"
        "def Mine(*args, **kwargs):\n    return None\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    yield path
    assert SIDE_EFFECT not in sys.modules
    assert not path.exists()


def code_names(marker: Path) -> dict[str, tuple[str, dict]]:
    """Each way to name code: (the "module:attr", the kwargs that make a call do harm)."""
    return {
        "os": ("os:system", {"command": f"touch {marker}"}),
        "eval": ("builtins:eval", {"source": f"open({str(marker)!r}, 'w')"}),
        "module": (f"{SIDE_EFFECT}:Mine", {}),
    }


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    """A Robot session log (two episodes of StROL) and its export, written once."""
    root = tmp_path_factory.mktemp("data")
    log = robot_session(root / "s.jsonl")
    mp = pytest.MonkeyPatch()
    mp.setenv("MINARI_DATASETS_PATH", str(root / "minari"))
    try:
        assert main(["export", "strol/base-v0", "--log", str(log)]) == 0
    finally:
        mp.undo()
    return root


def _dataset(exported: Path, tmp_path: Path, name: str) -> tuple[Path, dict]:
    """A copy of the exported dataset under MINARI_DATASETS_PATH as strol/<name>-v0."""
    folder = tmp_path / "minari" / "strol" / f"{name}-v0"
    shutil.copytree(exported / "minari" / "strol" / "base-v0", folder)
    meta_path = folder / "data" / "metadata.json"
    return meta_path, json.loads(meta_path.read_text())


def _spec(entry_point: str | None = None, **over) -> dict:
    """A registered-looking env spec (StROL-Robot-v0, its entry points), fields overridden."""
    registered = ENV_SPECS["StROL-Robot-v0"]
    spec = {
        "id": "StROL-Robot-v0",
        "entry_point": entry_point or registered["entry_point"],
        "reward_threshold": None,
        "nondeterministic": False,
        "max_episode_steps": 10,
        "order_enforce": True,
        "disable_env_checker": False,
        "kwargs": {},
        "additional_wrappers": [],
        "vector_entry_point": registered["vector_entry_point"],
    }
    return {**spec, **over}


def _wrapper(entry_point: str, kwargs: dict) -> dict:
    return {"name": "OnlineLearningWrapper", "entry_point": entry_point, "kwargs": kwargs}


def _tamper(place: str, spec: str, kwargs: dict) -> tuple[dict, bool]:
    """(metadata changes, whether the spaces are deleted) naming ``spec`` at ``place``."""
    learner = {"learner": spec, "learner_kwargs": None, "replace_reward": False}
    ours = wrappers()["OnlineLearningWrapper"]
    cases = {
        # the repro: no spaces, so Minari builds the env_spec's env to learn them
        "entry_point": (_spec(spec, id="X-v0", kwargs=kwargs), True),
        "registered-id": (_spec(spec, kwargs=kwargs), True),
        "wrapper": (_spec(additional_wrappers=[_wrapper(spec, kwargs)]), True),
        "vector": (_spec(vector_entry_point=spec), True),
        "env-kwargs": (_spec(kwargs={"task": spec, **kwargs}), True),
        "wrapper-kwargs": (_spec(additional_wrappers=[_wrapper(ours, learner)]), False),
        "with-spaces": (_spec(spec, kwargs=kwargs), False),  # recover_environment would run it
    }
    env_spec, drop = cases[place]
    return {"env_spec": json.dumps(env_spec)}, drop


PLACES = [
    "entry_point",
    "registered-id",
    "wrapper",
    "vector",
    "env-kwargs",
    "wrapper-kwargs",
    "with-spaces",
]


@pytest.mark.parametrize("how", ["os", "eval", "module"])
def test_datasets_naming_code_are_refused(how, exported, tmp_path, marker, capsys):
    """The issue's repro with code in ``entry_point``, ``additional_wrappers[0].entry_point``,
    ``vector_entry_point``, kwargs, and in ``eval_env_spec``: exit 2 naming the file."""
    spec, kwargs = code_names(marker)[how]
    for place in [*PLACES, "eval"]:
        meta_path, meta = _dataset(exported, tmp_path, place)
        if place == "eval":
            meta["eval_env_spec"] = json.dumps(_spec(spec, kwargs=kwargs))
        else:
            changes, drop = _tamper(place, spec, kwargs)
            meta.update(changes)
            if drop:
                del meta["observation_space"], meta["action_space"]
        meta_path.write_text(json.dumps(meta))
        for source in (f"strol/{place}-v0", str(meta_path.parent.parent)):
            line = cli_error(["replay", source, "--learners", "gradient", "--no-plots"], capsys)
            assert str(meta_path) in line, (place, line)
            assert not marker.exists(), place
        with pytest.raises(ValueError, match=r"metadata\.json"):
            read_any(f"strol/{place}-v0")


def test_minari_without_the_gate_runs_the_repro(exported, tmp_path, marker):
    """The positive control: Minari itself runs the repro's command (what the gate stops)."""
    meta_path, meta = _dataset(exported, tmp_path, "control")
    spec, kwargs = code_names(marker)["os"]
    meta.update(_tamper("entry_point", spec, kwargs)[0])
    del meta["observation_space"], meta["action_space"]
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(Exception):  # noqa: B017 (os.system returns an int, not an env)
        minari.MinariDataset(meta_path.parent)
    assert marker.exists()
    marker.unlink()  # the fixture's own check is for the readers under test


def test_gate_refuses_what_is_not_ours(exported, tmp_path, marker, capsys):
    """A missing space, an unknown space type, a Box sized for an allocation, an unknown key
    or an unregistered id are refused naming the file; the exported dataset passes."""
    good = _spec(additional_wrappers=[_wrapper(wrappers()["OnlineLearningWrapper"], {})])
    assert check_env_spec("spec", json.dumps(good))["id"] == "StROL-Robot-v0"
    big = {"type": "Box", "dtype": "float32", "shape": [10**9], "low": [0], "high": [0]}
    cases = {
        "no-space": {"observation_space": None},
        "text-space": {"action_space": json.dumps({"type": "Text", "max_length": 10**9})},
        "big-box": {"action_space": json.dumps(big)},
        "unknown-key": {"env_spec": json.dumps({**_spec(), "entry_point_2": "os:system"})},
        "other-env": {"env_spec": json.dumps(_spec(id="CartPole-v1"))},
        "not-json": {"env_spec": "{"},
    }
    for name, change in cases.items():
        meta_path, meta = _dataset(exported, tmp_path, name)
        meta.update(change)
        meta_path.write_text(json.dumps({k: v for k, v in meta.items() if v is not None}))
        line = cli_error(["replay", f"strol/{name}-v0", "--learners", "gradient"], capsys)
        assert str(meta_path) in line, (name, line)
    shutil.copytree(exported / "minari" / "strol", tmp_path / "minari" / "ours")
    out = tmp_path / "out"
    argv = ["replay", "ours/base-v0", "--learners", "gradient", "--no-plots", "--out", str(out)]
    assert cli(argv) == 0 and (out / "replay.csv").is_file()


def _log_lines(log: Path) -> list[dict]:
    return [json.loads(line) for line in log.read_text().splitlines()]


def test_session_logs_naming_code(exported, tmp_path, marker, capsys):
    """A log's Task naming code is refused at file:1; its learner and env kwargs are names
    that replay never looks up (the replay runs, imports nothing); a dataset's header too."""
    lines = _log_lines(exported / "s.jsonl")
    for how, (spec, _) in code_names(marker).items():
        bad = tmp_path / f"task-{how}.jsonl"
        bad.write_text("\n".join(json.dumps(r) for r in [{**lines[0], "task": spec}, *lines[1:]]))
        line = cli_error(["replay", str(bad), "--learners", "gradient", "--no-plots"], capsys)
        assert f"{bad}:1" in line and spec in line
        names = tmp_path / f"names-{how}.jsonl"
        header = {**lines[0], "learner": spec, "env_kwargs": {"task": spec, "human": spec}}
        names.write_text("\n".join(json.dumps(r) for r in [header, *lines[1:]]))
        out = tmp_path / f"out-{how}"
        argv = ["replay", str(names), "--learners", "gradient", "--no-plots", "--out", str(out)]
        assert cli(argv) == 0 and (out / "replay.csv").is_file()
        meta_path, meta = _dataset(exported, tmp_path, f"header-{how}")
        header = json.loads(meta["strol_session_header"])
        meta["strol_session_header"] = json.dumps({**header, "task": spec})
        meta_path.write_text(json.dumps(meta))
        line = cli_error(["replay", f"strol/header-{how}-v0", "--learners", "gradient"], capsys)
        assert spec in line


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    """A small results folder (Robot, two learners, two runs)."""
    folder = tmp_path_factory.mktemp("results") / "res"
    argv = ["run", "--env", "robot", "--learners", "gradient,strol", "--runs", "2"]
    assert main([*argv, "--jobs", "1", "--quiet", "--no-plots", "--out", str(folder)]) == 0
    return folder


def test_results_folders_and_plugin_lists_naming_code(results, tmp_path, marker, capsys):
    """meta.json's plugin list, learners, human, prior and Task naming code: ``report`` reads
    the folder's config (whose recomputed hash no longer matches: refused) and imports nothing,
    nor does ``run`` resuming it;
    records of another condition than their unit's are refused."""
    for how, (spec, _) in code_names(marker).items():
        for place in ("plugins", "human", "prior", "task", "learners"):
            folder = tmp_path / f"{how}-{place}"
            shutil.copytree(results, folder)
            meta = json.loads((folder / "meta.json").read_text())
            config, exp = meta["config"], meta["config"]["experiments"][0]
            if place == "plugins":
                config["plugins"] = {k: {"mine": spec} for k in ("learner", "human", "task")}
                config["plugins"]["condition"] = {"mine": spec}
            elif place in ("human", "prior"):
                exp["condition"][place] = spec
            elif place == "task":
                exp["task"] = spec
            else:  # a learner named by module:attr, its records relabelled to match
                config["learners"] = ["gradient", spec]
                config["reference"] = "gradient"
                for p in (folder / "records").glob("*.json"):
                    unit = json.loads(p.read_text())
                    for r in unit["records"]:
                        r["learner"] = spec if r["learner"] == "strol" else r["learner"]
                    p.write_text(json.dumps(unit))
            (folder / "meta.json").write_text(json.dumps(meta))
            # the edit changed the config, so its recomputed hash no longer matches: refused
            # (exit 2, one line naming the file), and nothing the file names was imported
            assert cli(["report", str(folder), "--no-plots"]) == 2, (how, place)
            err = capsys.readouterr().err
            assert "Traceback" not in err and "config_hash" in err, (how, place)
            assert not marker.exists(), (how, place)
        # resuming compares the config hash; the command's own config runs, the file's
        # plugin list is never installed
        folder = tmp_path / f"{how}-plugins"
        argv = ["run", "--env", "robot", "--learners", "gradient,strol", "--runs", "2"]
        assert cli([*argv, "--jobs", "1", "--quiet", "--no-plots", "--out", str(folder)]) == 0
    record = next((results / "records").glob("*.json"))
    folder = tmp_path / "other-condition"
    shutil.copytree(results, folder)
    unit = json.loads(record.read_text())
    unit["records"][0]["condition"] = "os:system"
    (folder / "records" / record.name).write_text(json.dumps(unit))
    assert "is not its unit's" in cli_error(["report", str(folder)], capsys)


class _Reduce:
    """A pickled object whose loading would call ``os.system(command)``."""

    def __init__(self, command: str) -> None:
        self.command = command

    def __reduce__(self):
        import os

        return (os.system, (self.command,))


def test_checkpoints_and_sidecars_naming_code(tmp_path, marker):
    """Weights that unpickle to a call, and sidecars naming code in every field, are refused
    by the learner that loads them (weights_only, the sidecar checked against the Task)."""
    task = make_task("robot")
    path = tmp_path / "g.pt"
    net = CorrectionNet(task.network_input_dim, task.dim, [8], "radial")
    save_checkpoint(path, net, task, "strol")
    good = json.loads(path.with_suffix(".json").read_text())
    make_learner("strol", task=task, checkpoint=str(path))  # the base case loads
    torch.save({"w": _Reduce(f"touch {marker}")}, path)
    rehash_sidecar(path)  # the sidecar vouches for these bytes: only weights_only stands
    with pytest.raises(ValueError, match="cannot read these weights"):
        make_learner("strol", task=task, checkpoint=str(path))
    save_checkpoint(path.with_name("h.pt"), net, task, "strol")
    other = path.with_name("h.pt")
    for how, (spec, _) in code_names(marker).items():
        for field in ("kind", "network", "task", "training"):
            side = {**good, field: spec if field == "kind" else {"in_dim": spec, "task": spec}}
            other.with_suffix(".json").write_text(json.dumps(side))
            rehash_sidecar(other)
            if field == "training":  # the training config is a record, never looked up
                make_learner("strol", task=task, checkpoint=str(other))
            else:
                with pytest.raises(ValueError, match="checkpoint"):
                    make_learner("strol", task=task, checkpoint=str(other))
            assert not marker.exists(), (how, field)


def test_experiment_tables_naming_code(tmp_path, marker):
    """The experiments' own readers (runs.csv, summary/stats CSV, confirm.json, study.json)
    read names as strings: a file full of module:attr imports nothing."""
    from lab.checks.compare_learners import load_runs
    from lab.checks.cross_kernel import folder_verdicts, means
    from strol_gym.metrics import RUN_METRICS

    spec = f"{SIDE_EFFECT}:Mine"
    with open(tmp_path / "runs.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["env", "condition", "learner", "seed", *RUN_METRICS])
        w.writerow([spec, "os:system", "builtins:eval", 0, *[0.5] * len(RUN_METRICS)])
    assert load_runs(tmp_path)[(spec, "os:system", "builtins:eval")][0][RUN_METRICS[0]] == 0.5
    header = ["env", "condition", "learner", "metric", "mean", "baseline", "significant"]
    for name in ("summary.csv", "stats.csv"):
        with open(tmp_path / name, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow([*header, "mean_diff"])
            w.writerow([spec, spec, "os:system", "regret", "1.0", spec, "true", "-1"])
    (tmp_path / "confirm.json").write_text(json.dumps({"verdicts": {spec: "os:system"}}))
    (tmp_path / "study.json").write_text(json.dumps({"verdicts": [{"task": 1, "verdict": spec}]}))
    assert means(tmp_path) == {(spec, spec, "os:system", "regret"): 1.0}
    got = folder_verdicts(tmp_path)
    assert got[("confirm", spec)] == "os:system" and got[("H3", "Task 1")] == spec


# ---------------------------------------------------------------------- export ids
@pytest.mark.parametrize(
    "dataset_id",
    ["../x/evil-v0", "/tmp/abs/evil-v0", "strol//evil-v0", "x", "strol/x", "a/../b-v0", "./a-v0"],
)
def test_export_refuses_bad_ids_before_creating_anything(
    dataset_id, exported, tmp_path, monkeypatch, capsys
):
    """``namespace/name-vN`` only: a rejected id exits 2 and leaves nothing behind (not even
    the datasets root), from a log or from runs."""
    root = tmp_path / "root" / "minari"
    root.parent.mkdir()
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    argv = ["export", dataset_id, "--log", str(exported / "s.jsonl")]
    assert "dataset_id" in cli_error(argv, capsys)
    runs = ["export", dataset_id, "--env", "robot", "--runs", "1"]
    assert "dataset_id" in cli_error(runs, capsys)
    assert list(root.parent.iterdir()) == [] and not Path("/tmp/abs").exists()


def test_export_refuses_a_taken_id(exported, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(exported / "minari"))
    argv = ["export", "strol/base-v0", "--log", str(exported / "s.jsonl")]
    assert "already exists" in cli_error(argv, capsys)


# ---------------------------------------------------------------------- header names
def test_headers_name_registered_pieces_and_study_v1_exports_replay(tmp_path, monkeypatch):
    """A Study-v1 session's header names ``study-task1-v1`` and its env kwargs registered
    names (no module path anywhere); its export replays to the logged θ̂; an old header
    naming our Task by module path is read through the fixed table, another path refused."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    log = tmp_path / "v1.jsonl"
    base = gym.make("StROL-Study-v1", task="study-task1-v1", person="observer")
    env = SessionLogger(OnlineLearningWrapper(base, "gradient"), log)
    env.reset(seed=1)
    task, learner = env.unwrapped.task, env.learner
    rng = np.random.default_rng(0)
    for _ in range(3):  # corrections the learner really makes (an env step is 60 s of pushes)
        x, u_h = rng.normal(0.5, 0.1, task.state_dim), 0.05 * rng.normal(size=task.action_dim)
        before = learner.theta.copy()
        after = learner.update(x, u_h, np.zeros(task.action_dim))
        env.writer.correction(x=x, u_h=u_h, u_r=np.zeros(task.action_dim),
                              theta_hat_before=before, theta_hat_after=after)  # fmt: skip
    env.close()
    header = _log_lines(log)[0]
    assert header["task"] == "study-task1-v1"
    names = [header["task"], header["learner"], *header["env_kwargs"].values()]
    assert names == ["study-task1-v1", "gradient", "study-task1-v1", "observer"]
    assert cli(["export", "strol/study-v1-v0", "--log", str(log)]) == 0
    session = read_any("strol/study-v1-v0")
    replayed = replay_session(session, ["gradient"])["gradient"][0]
    logged = [c["theta_hat_after"] for c in read_session(log).episodes[0].corrections]
    np.testing.assert_array_equal(replayed[1:], logged)

    lines = _log_lines(log)
    assert LEGACY_TASKS["strol_gym.tasks.study:StudyTask1V1"] == "study-task1-v1"
    for path, code in (("strol_gym.tasks.study:StudyTask1V1", 0), ("strol_gym.tasks:TASKS", 2)):
        old = tmp_path / f"old-{code}.jsonl"
        old.write_text("\n".join(json.dumps(r) for r in [{**lines[0], "task": path}, *lines[1:]]))
        out = tmp_path / f"out-{code}"
        argv = ["replay", str(old), "--learners", "gradient", "--no-plots", "--out", str(out)]
        assert cli(argv) == code, path


def test_study_pickles_naming_code(tmp_path, marker):
    """The authors' study logs (import-study's plain-data unpickler): a pickle whose loading
    would call os.system, eval, or import the side-effect module is refused, and runs nothing."""
    from strol_gym.benchmarks.sessions.plain_pickle import PickleRefused, load_plain_pickle

    for how, (spec, kwargs) in code_names(marker).items():
        module, name = spec.split(":")
        arg = json.dumps(next(iter(kwargs.values()), ""))  # a quoted string pickle reads as is
        path = tmp_path / f"{how}.pkl"  # protocol 0 by hand: GLOBAL module name, MARK, arg, REDUCE
        path.write_bytes(f"c{module}\n{name}\n(S{arg}\ntR.".encode())
        with pytest.raises(PickleRefused):
            load_plain_pickle(path)
        assert not marker.exists(), how
