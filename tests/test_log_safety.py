"""A session log from someone else never runs code: it names registered pieces only, and every
malformed log exits 2 naming file:line. Each case runs ``strol-bench replay`` in its own process,
so an abort or exit a log could trigger would show as that process's status."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from strol_gym.tasks import make_task
from strol_gym.wrappers.session_log import SessionWriter

TASK = "study-task1"


def _records() -> list[dict]:
    """A valid log's lines: header, one episode, one correction."""
    task = make_task(TASK)
    rng = np.random.default_rng(0)
    return [
        {
            "type": "header",
            "format": "strol-session",
            "version": 1,
            "env_id": "StROL-Study-v0",
            "task": TASK,
            "task_describe": json.loads(json.dumps(task.describe())),
            "learner": "strol",
        },
        {"type": "episode", "seed": 0, "theta_hat0": [0.5] * task.dim, "theta_star": None},
        {
            "type": "correction",
            "x": rng.normal(size=task.state_dim).tolist(),
            "u_h": (0.1 * task.action_bound).tolist(),
            "u_r": [0.0] * task.action_dim,
            "correction_time": 0.5,
        },
    ]


def _write(path: Path, lines: list) -> Path:
    data = [x if isinstance(x, bytes) else json.dumps(x).encode() for x in lines]
    path.write_bytes(b"\n".join(data))
    return path


DRIVER = """
import contextlib, io, json, sys
from pathlib import Path
from strol_gym.benchmarks.cli import main

results = []
for argv in json.loads(sys.argv[1]):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:
            code = e.code
    ran = Path("ran.txt").exists()
    results.append({"code": code, "out": out.getvalue(), "err": err.getvalue(), "ran": ran})
print(json.dumps(results))
"""


def _replay_all(runs: list[list[str]], cwd: Path) -> list[dict]:
    """``strol-bench replay`` on each argument list, in turn, in one fresh process (whose
    status would show an abort or exit a log triggered): exit status, output, and whether the
    side-effect module had been imported by then."""
    env = {**os.environ, "PYTHONPATH": str(cwd)}  # the side-effect module is importable
    argvs = [
        ["replay", *run, "--learners", "gradient", "--no-plots", "--out", str(cwd / "out")]
        for run in runs
    ]
    cmd = [sys.executable, "-c", DRIVER, json.dumps(argvs)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=cwd, env=env)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    return json.loads(done.stdout.splitlines()[-1])


SIDE_EFFECT = """
from pathlib import Path
Path(__file__).with_name("ran.txt").write_text("imported")
from strol_gym.tasks import make_task
Mine = type(make_task("study-task1"))
"""


def _case(name: str, recs: list[dict]) -> tuple[list, int]:
    """The lines of malformed log ``name`` and the line its error must name."""
    header, episode, corr = recs
    if name in ("os:abort", "sys:exit", "sideeffect:Mine"):
        return [{**header, "task": name}, episode, corr], 1
    if name == "nested":
        return [header, episode, b"[" * 100_000], 3
    if name == "string-describe":
        return [{**header, "task_describe": "features"}, episode, corr], 1
    if name == "huge-integer":
        return [header, episode, b'{"type": "correction", "x": [' + b"9" * 5000 + b"]}"], 3
    if name == "binary":
        return [header, bytes(range(256)) * 4, corr], 2
    if name == "unknown-task":
        return [{**header, "task": "no-such-task"}, episode, corr], 1
    raise AssertionError(name)


CASES = [
    "os:abort",
    "sys:exit",
    "sideeffect:Mine",
    "nested",
    "string-describe",
    "huge-integer",
    "binary",
    "unknown-task",
]


def test_logs_never_run_code(tmp_path):
    """Every malformed log exits 2 with one line naming file:line and runs nothing; a Task of
    the user's own module is accepted only once the user loads it with --plugin; the valid
    base of the malformed cases replays (so each case tests one fault)."""
    (tmp_path / "sideeffect.py").write_text(SIDE_EFFECT)
    recs = _records()
    runs, where = [], []
    for name in CASES:
        lines, line_no = _case(name, recs)
        log = _write(tmp_path / f"bad-{name.replace(':', '_')}.jsonl", lines)
        runs.append([str(log)])
        where.append(f"{log}:{line_no}:")
    good = tmp_path / "good.jsonl"
    writer = SessionWriter(good, {k: v for k, v in recs[0].items() if k not in ("type", "format")})
    writer.episode(**{k: v for k, v in recs[1].items() if k != "type"})
    writer.correction(**{k: v for k, v in recs[2].items() if k != "type"})
    writer.close()
    mine = _write(tmp_path / "mine.jsonl", [{**recs[0], "task": "sideeffect:Mine"}, *recs[1:]])
    runs += [[str(good)], [str(mine)], [str(mine), "--plugin", "sideeffect"]]

    results = _replay_all(runs, tmp_path)
    for name, at, r in zip(CASES, where, results, strict=False):
        err = r["err"].strip().splitlines()
        assert r["code"] == 2, (name, r)
        assert len(err) == 1 and at in err[0], (name, r)
        assert "Traceback" not in r["err"] and r["out"] == "", (name, r)
        assert not r["ran"], name  # the module the log named was never imported
    good_run, refused, accepted = results[len(CASES) :]
    assert good_run["code"] == 0 and "1 correction(s)" in good_run["out"], good_run
    assert refused["code"] == 2 and "--plugin sideeffect" in refused["err"], refused
    assert not refused["ran"]
    assert accepted["code"] == 0 and accepted["ran"], accepted
    assert (tmp_path / "out" / "replay.csv").exists()
