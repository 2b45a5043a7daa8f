"""The results folder's lock: one holder under a widened race window, on a fresh folder and on
a killed run's folder; another host's lock kept unless forced; recycled pids; leftovers."""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from strol_gym.benchmarks.engine import lock as lk

WINDOW = 0.15  # seconds a contender sleeps between creating its lock file and writing it


def _legacy_acquire(path: Path) -> None:
    """The lock as it was before (O_EXCL create, then write the pid), kept here to show the
    race the new lock closes; the sleep widens the window between create and write."""
    lock = path / lk.LOCK
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            try:
                pid = int(lock.read_text().strip() or "0")
            except (OSError, ValueError):
                pid = 0
            if pid > 0 and pid != os.getpid() and lk._pid_alive(pid):
                raise RuntimeError("in use") from None
            lock.unlink(missing_ok=True)
            continue
        time.sleep(WINDOW)
        with os.fdopen(fd, "w") as f:
            f.write(f"{os.getpid()}\n")
        return
    raise RuntimeError("could not take it")


def _contender(path: str, legacy: bool, barrier, held) -> None:
    if not legacy:
        lk._WRITE_HOOK.append(lambda: time.sleep(WINDOW))
    barrier.wait()
    try:
        (_legacy_acquire if legacy else lk.hold_folder)(Path(path))
    except (RuntimeError, lk.LockError):
        barrier.wait()
        return
    with held.get_lock():
        held.value += 1
    barrier.wait()  # everyone has tried while the winners still hold it


def _holders(path: Path, legacy: bool, n: int = 3) -> int:
    ctx = mp.get_context("fork")
    barrier, held = ctx.Barrier(n), ctx.Value("i", 0)
    procs = [
        ctx.Process(target=_contender, args=(str(path), legacy, barrier, held)) for _ in range(n)
    ]
    for p in procs:
        p.start()
    for p in procs:
        p.join(30)
        assert p.exitcode == 0
    return held.value


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


@pytest.mark.parametrize("stale", [False, True], ids=["fresh", "killed-run"])
def test_two_holders_with_the_old_lock_one_with_the_new(tmp_path, stale):
    counts = {}
    for legacy in (True, False):
        trials = 1 if legacy else 4
        got = []
        for t in range(trials):
            d = tmp_path / f"{legacy}-{t}"
            d.mkdir()
            if stale:
                (d / lk.LOCK).write_text(f"{_dead_pid()}\n")
            got.append(_holders(d, legacy))
        counts[legacy] = got
    assert counts[True] == [max(counts[True])] and counts[True][0] >= 2  # the race, shown
    assert counts[False] == [1, 1, 1, 1]  # exactly one holder, every trial


def _write_lock(d: Path, **fields) -> None:
    owner = {"host": socket.gethostname(), "pid": os.getpid(), "start": None, "boot": None}
    owner.update(fields)
    (d / lk.LOCK).write_text(json.dumps(owner))


def test_another_hosts_lock_is_kept_unless_forced(tmp_path, capsys):
    _write_lock(tmp_path, host="node-17", pid=os.getpid())
    with pytest.raises(lk.LockError, match=r"host node-17, pid .*rerun with --force"):
        lk.hold_folder(tmp_path)
    lk.hold_folder(tmp_path, force=True)
    assert "forced" in capsys.readouterr().err
    assert json.loads((tmp_path / lk.LOCK).read_text())["host"] == lk.host()
    lk.release_folder(tmp_path)
    assert not (tmp_path / lk.LOCK).exists()


def test_a_live_local_run_is_never_displaced_even_forced(tmp_path):
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        time.sleep(0.05)
        _write_lock(tmp_path, pid=other.pid, start=lk.start_time(other.pid))
        for force in (False, True):
            with pytest.raises(lk.LockError, match=rf"pid {other.pid}.*wait for it"):
                lk.hold_folder(tmp_path, force=force)
    finally:
        other.kill()
        other.wait()


@pytest.mark.skipif(lk.start_time(os.getpid()) is None, reason="needs /proc start times")
def test_a_recycled_pid_does_not_block(tmp_path, capsys):
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:  # a live process now owns the lock's pid, but it started at another time
        _write_lock(tmp_path, pid=other.pid, start=12345)
        lk.hold_folder(tmp_path)
        assert "is gone" in capsys.readouterr().err
    finally:
        other.kill()
        other.wait()


def test_an_unreadable_lock_says_how_to_clear_it(tmp_path):
    (tmp_path / lk.LOCK).write_text("garbage")
    with pytest.raises(lk.LockError, match=r"not a strol-bench lock.*delete .*\.lock"):
        lk.hold_folder(tmp_path)


def test_temp_names_carry_host_and_pid_and_dead_writers_leftovers_go(tmp_path):
    from strol_gym.files import temp_beside

    tmp = temp_beside(tmp_path / "meta.json", lambda p: p.write_text("{}"))
    assert f".{lk.host()}-{os.getpid()}." in tmp.name
    dead = tmp_path / f".meta.json.{lk.host()}-{_dead_pid()}.abc.tmp"
    other_host = tmp_path / ".meta.json.node-17-1.abc.tmp"
    dead.write_text("{")
    other_host.write_text("{")
    assert lk.clean_leftovers(tmp_path) == [dead]
    assert tmp.exists() and other_host.exists()  # a live writer's and another host's stay


def _folder_begun(path: Path, pid: int, start: int | None, extra: str | None = None) -> Path:
    """A results folder as a run leaves it between taking the lock and writing meta.json."""
    path.mkdir()
    (path / "records").mkdir()
    _write_lock(path, pid=pid, start=start)
    if extra:
        (path / extra).write_text("not ours")
    return path


def test_a_folder_being_created_names_its_run_not_a_foreign_folder(tmp_path, capsys):
    """Three runs started at once on one --out: the losers said the folder was "not a
    strol-bench results folder" (it had the winner's lock, no meta.json yet)."""
    from cli_checks import cli_error

    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        time.sleep(0.05)
        out = _folder_begun(tmp_path / "r", other.pid, lk.start_time(other.pid))
        line = cli_error(["run", "--env", "robot", "--runs", "1", "--out", str(out)], capsys)
        assert f"in use by another strol-bench run (host {lk.host()}, pid {other.pid}" in line
        assert not (out / "meta.json").exists()
    finally:
        other.kill()
        other.wait()


def test_a_folder_begun_by_a_gone_run_is_created_anew(tmp_path, capsys):
    from strol_gym.benchmarks.engine.config import paper_config
    from strol_gym.benchmarks.engine.results import ResultsDir, ResultsError

    cfg = paper_config(["robot"], runs=1, learners=("gradient", "strol"), block=1)
    out = _folder_begun(tmp_path / "r", _dead_pid(), None)
    ResultsDir.open(out, cfg)
    assert (out / "meta.json").exists() and "is gone" in capsys.readouterr().err
    assert json.loads((out / lk.LOCK).read_text())["pid"] == os.getpid()
    lk.release_folder(out)
    foreign = _folder_begun(tmp_path / "f", _dead_pid(), None, extra="notes.txt")
    with pytest.raises(ResultsError, match="not a strol-bench results folder"):
        ResultsDir.open(foreign, cfg)  # something else is there: not taken
    assert (foreign / "notes.txt").exists() and not (foreign / "meta.json").exists()
    assert not (foreign / lk.LOCK).exists()  # the gone run's lock was taken over, then let go
