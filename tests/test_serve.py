"""strol-bench serve: the plan and its counterbalancing, what a page may send, and a real server
on 127.0.0.1 refusing bad input while it keeps serving and loses no log."""

from __future__ import annotations

import asyncio
import itertools
import json
import time
from pathlib import Path

import pytest

pytest.importorskip("starlette")
pytest.importorskip("uvicorn")
websockets = pytest.importorskip("websockets")

from strol_gym.benchmarks.serve import inputs  # noqa: E402
from strol_gym.benchmarks.serve.plan import (  # noqa: E402
    Participants,
    StudyPlan,
    latin_row,
    load_plan,
    schedule,
)
from strol_gym.wrappers.session_log import read_session  # noqa: E402

TOKEN = "test-token-0123456789"


def _plan(tmp_path: Path, **fields) -> Path:
    path = tmp_path / "plan.json"
    path.write_text(json.dumps({"name": "t", **fields}))
    return path


# ---------------------------------------------------------------------- the plan
def test_plan_fields_are_checked_and_named(tmp_path):
    (tmp_path / "consent.txt").write_text("You may stop at any time.")
    plan = load_plan(_plan(tmp_path, consent="consent.txt", learners=["one", "strol"]))
    assert plan.consent == "You may stop at any time." and plan.learners == ("one", "strol")
    bad = [
        ({"learners": ["strol_gym.learners:Evil"]}, "'learners'"),
        ({"learners": ["one", "one"]}, "'learners'"),
        ({"tasks": [4]}, "'tasks'"),
        ({"duration": 1e9}, "'duration'"),
        ({"consent": "../secret.txt"}, "'consent'"),
        ({"consent": "/etc/passwd"}, "'consent'"),
        ({"log": "x"}, "unknown field"),
    ]
    for fields, word in bad:
        with pytest.raises(ValueError, match=word):
            load_plan(_plan(tmp_path, **fields))
    with pytest.raises(ValueError, match="'name'"):
        load_plan(_plan(tmp_path, name="../up"))


def test_orders_are_latin_squares_over_learners_and_tasks():
    plan = StudyPlan(name="t", learners=("one", "mof", "strol"), tasks=(1, 2, 3))
    seen = set()
    for k in range(9):
        orders, sessions = schedule(plan, k)
        seen.add((tuple(orders["learners"]), tuple(orders["tasks"])))
        study = [s for s in sessions if not s.practice]
        # per learner: each Task on the arm, then the car; learners named by place only
        assert [s.kind for s in study] == (["arm"] * 3 + ["car"]) * 3
        assert [s.learner for s in study[::4]] == orders["learners"]
        assert [s.task for s in study[:3]] == orders["tasks"]
        assert all("one" not in s.label and "strol" not in s.label for s in sessions)
        assert [s.kind for s in sessions if s.practice] == ["arm", "car"]
    assert len(seen) == 9  # every pair of orders once in 9 participants
    firsts = [latin_row(("a", "b", "c"), r)[0] for r in range(3)]
    assert sorted(firsts) == ["a", "b", "c"]


def test_participants_survive_a_restart(tmp_path):
    plan = StudyPlan(name="t", learners=("one", "strol"))
    first = Participants(tmp_path, plan)
    a, ka, sessions = first.join()
    first.record(a, sessions[0], "x.jsonl", "truncated", 2)
    again = Participants(tmp_path, plan)  # a restarted server
    b, kb, _ = again.join()
    assert (ka, kb) == (0, 1) and a != b
    assert again.state["participants"][a]["sessions"][0]["corrections"] == 2
    with pytest.raises(ValueError, match="another plan"):
        Participants(tmp_path, StudyPlan(name="t", learners=("mof",)))


# ---------------------------------------------------------------------- what a page sends
def test_messages_are_parsed_or_refused():
    ok = inputs.parse('{"t": "input", "n": 3, "keys": ["W", "Shift"], "pad": null}')
    assert ok == {"t": "input", "n": 3, "keys": ["shift", "w"], "pad": None}
    pad = {"axes": [0.5, -1, 0, 0], "buttons": [0, 1]}
    assert inputs.parse(json.dumps({"t": "input", "n": 0, "keys": [], "pad": pad}))["pad"]
    assert inputs.parse('{"t": "start"}') == {"t": "start"}
    refused = [
        None,
        b"\xff\xfe",
        "{not json",
        "[1, 2]",
        "x" * (inputs.MAX_MESSAGE + 1),
        '{"t": "input", "n": 1, "keys": ["../../etc/passwd"], "pad": null}',
        '{"t": "input", "n": 1, "keys": [], "pad": null, "log": "/tmp/x.jsonl"}',
        '{"t": "input", "n": -1, "keys": [], "pad": null}',
        '{"t": "input", "n": 1, "keys": ["w"], "pad": {"axes": [1e9], "buttons": []}}',
        '{"t": "input", "n": 1, "keys": ["w"], "pad": {"axes": [], "buttons": [NaN]}}',
        '{"t": "input", "n": 1, "keys": ' + json.dumps(["w"] * 13) + ', "pad": null}',
        '{"t": "input", "n": 1, "keys": [[[["w"]]]], "pad": null}',
        '{"t": "run", "code": "import os"}',
        '{"t": "start", "task": 9}',
    ]
    for message in refused:
        with pytest.raises(inputs.Refused):
            inputs.parse(message)


def test_rate_limit_allows_a_burst_then_the_rate():
    limit = inputs.RateLimit(rate=10.0, burst=5.0)
    allowed = sum(limit.allow() for _ in range(50))
    assert 5 <= allowed <= 7  # the burst, and what refilled while the loop ran


# ---------------------------------------------------------------------- a real server
@pytest.fixture(scope="module")
def server(tmp_path_factory):
    from strol_gym.benchmarks.serve.app import Server, serve_in_thread

    out = tmp_path_factory.mktemp("serve")
    srv = Server(StudyPlan(practice=6.0, highway=False), out, TOKEN, fps=4.0)
    with serve_in_thread(srv) as url:
        yield srv, url


def _get(url: str) -> int:
    import urllib.error
    import urllib.request

    try:
        with urllib.request.urlopen(url, timeout=30) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


async def _visit(url: str, token: str = TOKEN) -> tuple[object, dict]:
    # no keepalive pings: on a loaded machine a late pong would end the test's connection
    ws = await websockets.connect(
        url.replace("http", "ws") + f"/ws?token={token}", ping_interval=None
    )
    hello = json.loads(await ws.recv())
    assert hello["t"] == "hello"
    assert json.loads(await ws.recv())["t"] == "next"
    return ws, hello


async def _until_frame(ws) -> None:
    async with asyncio.timeout(120):
        while not isinstance(await ws.recv(), bytes):
            pass


async def _replies(ws, n: int) -> list[dict]:
    out: list[dict] = []
    async with asyncio.timeout(30):
        while len(out) < n:
            m = await ws.recv()
            if isinstance(m, str) and json.loads(m)["t"] == "refused":
                out.append(json.loads(m))
    return out


def _end_reason(log: Path) -> str | None:
    for line in reversed(log.read_text().splitlines()):
        rec = json.loads(line)
        if rec["type"] == "end":
            return rec["reason"]
    return None


async def _wait_end(log_folder: Path) -> Path:
    async with asyncio.timeout(60):
        while True:
            logs = list(log_folder.glob("*.jsonl"))
            if logs and _end_reason(logs[0]) is not None:
                return logs[0]
            await asyncio.sleep(0.2)


def test_bad_input_is_refused_and_the_server_keeps_serving(server):
    srv, url = server
    # no token, a wrong one: refused on the page, the study's text and the websocket
    assert _get(f"{url}/") == 403
    assert _get(f"{url}/?token=wrong") == 403
    assert _get(f"{url}/api/intro") == 403
    assert _get(f"{url}/api/intro?token={TOKEN}") == 200
    assert _get(f"{url}/..%2f..%2fetc%2fpasswd?token={TOKEN}") == 404

    async def scenario() -> None:
        for token in ("", "wrong"):
            with pytest.raises(websockets.exceptions.InvalidStatus):
                await _visit(url, token)
        # a running session gets malformed, oversized, path-carrying and binary messages:
        # each is refused and the session goes on; a message past the socket's cap ends it
        ws, hello = await _visit(url)
        await ws.send(json.dumps({"t": "start"}))
        await _until_frame(ws)
        bad = [
            "{not json",
            "x" * 2000,
            json.dumps({"t": "input", "n": 1, "keys": ["../../etc/passwd"], "pad": None}),
            json.dumps({"t": "input", "n": 1, "keys": [], "pad": None, "log": "/tmp/x"}),
            b"\x00binary",
        ]
        for message in bad:
            await ws.send(message)
        assert len(await _replies(ws, len(bad))) == len(bad)
        await _until_frame(ws)  # still running
        await ws.send("y" * 10_000)  # beyond the websocket's 4 KiB cap: the server closes
        with pytest.raises(websockets.exceptions.ConnectionClosed):
            async with asyncio.timeout(30):
                while True:
                    await ws.recv()
        log = await _wait_end(srv.out / hello["participant"])
        assert _end_reason(log) == "connection closed"
        read_session(log)  # complete and readable

        # a flood: the connection is closed (1008) and its session ends with its end line
        ws, hello = await _visit(url)
        await ws.send(json.dumps({"t": "start"}))
        await _until_frame(ws)
        flood = json.dumps({"t": "input", "n": 1, "keys": ["w"], "pad": None})
        with pytest.raises(websockets.exceptions.ConnectionClosed) as closed:
            async with asyncio.timeout(60):
                for _ in range(2000):
                    await ws.send(flood)
                while True:
                    await ws.recv()
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008
        log = await _wait_end(srv.out / hello["participant"])
        assert _end_reason(log).startswith("connection closed by the server (too many")
        read_session(log)

        # the server still serves a new visitor, and every session so far is on record
        ws, hello = await _visit(url)
        await ws.close()

    asyncio.run(scenario())
    deadline = time.monotonic() + 30  # the server records a session once its process is gone
    while True:
        people = json.loads((srv.out / "participants.json").read_text())["participants"]
        recorded = list(itertools.chain.from_iterable(p["sessions"] for p in people.values()))
        if len(recorded) == 2 or time.monotonic() > deadline:
            break
        time.sleep(0.2)
    assert len(people) == 3
    assert sorted(s["reason"].split(" (")[0] for s in recorded) == [
        "connection closed",
        "connection closed by the server",
    ]


# ---------------------------------------------------------------------- the study as data
def test_a_study_exports_as_minari_datasets_and_reads_back(tmp_path, monkeypatch):
    pytest.importorskip("minari")
    from strol_gym.benchmarks.serve.export import export_study
    from strol_gym.benchmarks.serve.plan import SessionSpec
    from strol_gym.benchmarks.sessions.drive import run_drive
    from strol_gym.benchmarks.sessions.export import export_session, read_dataset

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    plan = StudyPlan(name="pilot", learners=("strol",), highway=True)
    people = Participants(tmp_path / "out", plan)
    logs = []
    for k in range(2):  # two participants' car sessions (fast, no window), and a practice
        pid, _, sessions = people.join()
        (tmp_path / "out" / pid).mkdir()
        for spec in (sessions[1], next(s for s in sessions if s.kind == "car" and not s.practice)):
            log = tmp_path / "out" / pid / spec.log_name(k)
            run_drive(learner="strol", seed=k, log=log, duration=1.0, realtime=False,
                      keys=lambda: (1.0, 0.0), window=False)  # fmt: skip
            people.record(pid, spec, str(log.relative_to(tmp_path / "out")), "truncated", 4)
            logs.append((spec, log))
    # a session whose process died before its header is skipped, not exported
    broken = SessionSpec("car", "x", "strol", 0, 5.0, 9, False)
    (tmp_path / "out" / pid / "09-car-highway-strol.jsonl").write_text("")
    people.record(pid, broken, f"{pid}/09-car-highway-strol.jsonl", "failed: x", 0)
    plan_file = _plan(tmp_path, name="pilot", learners=["strol"])
    assert load_plan(plan_file) == plan
    from strol_gym.benchmarks.cli import main

    out = str(tmp_path / "out")
    assert main(["serve", "--study", str(plan_file), "--out", out, "--export"]) == 0
    with pytest.raises(ValueError, match="already exists"):  # never overwritten
        export_study(tmp_path / "out", plan)
    back = read_dataset("pilot/car-strol-v0")
    study = [log for spec, log in logs if not spec.practice]
    assert len(back.episodes) == 2
    for episode, log in zip(back.episodes, study, strict=True):
        assert len(episode.corrections) == len(read_session(log).episodes[0].corrections) > 0
    # one dataset holds one setting: another learner's log is refused beside them
    other = tmp_path / "gradient.jsonl"
    run_drive(learner="gradient", seed=0, log=other, duration=1.0, realtime=False,
              keys=lambda: (1.0, 0.0), window=False)  # fmt: skip
    with pytest.raises(ValueError, match="learner differ"):
        export_session([study[0], other], "pilot/mixed-v0")


def test_the_page_gamepad_and_keys_reach_the_session_by_the_shared_mapping():
    import multiprocessing

    from strol_gym.benchmarks.serve.worker import Inbox
    from strol_gym.benchmarks.sessions import keys as keymap

    here, there = multiprocessing.Pipe()
    inbox = Inbox(there)
    # a gamepad's left stick pushed right (standard mapping) and Up held on the keyboard
    pad = {"axes": [1.0, 0.0, 0.0, 0.0], "buttons": [0.0] * 8}
    here.send(("input", inputs.parse(json.dumps({"t": "input", "n": 7, "keys": ["ArrowUp"],
                                                 "pad": pad}))))  # fmt: skip
    deadline = time.monotonic() + 10
    while inbox.ack != 7 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert inbox.ack == 7
    want = keymap.pad_arm_intent(keymap.Pad.of(pad["axes"], pad["buttons"]))
    assert inbox.arm_intent() == want and want.right == 1.0  # the stick wins over the keys
    assert inbox.car_intent() == (1.0, 1.0)  # keys accelerate, the stick steers right
    here.send(("input", {"t": "input", "n": 8, "keys": ["arrowup"], "pad": None}))
    while inbox.ack != 8 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert inbox.arm_intent() == keymap.arm_intent(["arrowup"])  # no pad: the keys
    here.close()  # the server went away: the session is told to end
    while inbox.stop_reason is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert inbox.stop_reason == "connection closed"


def test_visitors_beyond_the_cap_are_asked_to_come_back(tmp_path):
    from strol_gym.benchmarks.serve.app import Server, serve_in_thread

    srv = Server(StudyPlan(practice=6.0), tmp_path, TOKEN, max_visits=1)

    async def scenario(url: str) -> None:
        first, _ = await _visit(url)
        second = await websockets.connect(url.replace("http", "ws") + f"/ws?token={TOKEN}")
        assert json.loads(await second.recv()) == {"t": "full"}
        with pytest.raises(websockets.exceptions.ConnectionClosed):
            await second.recv()
        await first.close()

    with serve_in_thread(srv) as url:
        asyncio.run(scenario(url))
    people = json.loads((tmp_path / "participants.json").read_text())["participants"]
    assert len(people) == 1  # the one turned away got no id


def test_the_panel_reaches_the_page_from_either_layout_of_interacts_overlay():
    import mujoco

    from strol_gym.benchmarks.serve.worker import arm_panel
    from strol_gym.benchmarks.sessions import keys as keymap

    grid = mujoco.mjtGridPos
    push = keymap.ArmPush().step(keymap.Intent(right=1.0), 1.0, 150.0)
    cues = (0, grid.mjGRID_TOPRIGHT, "TOO HARD: the arm braked\nreal-time factor 0.98", "")
    top = grid.mjGRID_TOPLEFT
    one_column = (0, top, "time: 1.0 s\ncorrections: 2\n\nHOW: drag\nTEACH: low", "")
    two_columns = (0, top, "time\ncorrections\n\nHOW\nTEACH", "1.0 s\n2\n\ndrag\nlow")
    for left in (one_column, two_columns):
        panel = arm_panel([left, cues], push)
        assert panel["state"] == ["time: 1.0 s", "corrections: 2"]  # the mouse's help left out
        assert panel["teach"] == "low" and panel["cues"][0].startswith("TOO HARD")
        assert panel["push"] == 40.0 and not panel["harder"]
