"""What both person modes of ``strol-bench interact`` share (the arm, ``interact``; the car,
``drive``): the wall-clock pace of the physics and the default log path."""

from __future__ import annotations

import contextlib
import datetime as dt
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def default_log_path() -> Path:
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    return Path("sessions") / f"session-{stamp}.jsonl"


class Pace:
    """Physics at wall-clock time whatever the viewer costs: the env steps on a schedule of
    one control step per ``CONTROL_DT``; the viewer is synced (the person's push read, the
    scene copied for drawing) only when the physics is not behind, and at least every
    ``max_skip`` steps. The whole session's real-time factor is ``factor``."""

    max_lag = 1.0
    """s behind the schedule beyond which it restarts from now (no fast-forward after it)."""

    def __init__(self, dt: float, realtime: bool, max_skip: int = 4) -> None:
        self.dt, self.realtime, self.max_skip = dt, realtime, max_skip
        self.start = self.t0 = time.perf_counter()
        self.skipped = 0
        self.steps = 0
        self.scheduled = 0  # steps since ``t0``, the schedule's origin

    def sync_now(self) -> bool:
        """Whether to sync the viewer before this step (always when not paced)."""
        behind = time.perf_counter() - self.t0 - self.scheduled * self.dt > self.dt
        if self.realtime and behind and self.skipped < self.max_skip:
            self.skipped += 1
            return False
        self.skipped = 0
        return True

    def wait(self) -> None:
        """After a step: sleep until its end on the wall clock (paced only)."""
        self.steps += 1
        self.scheduled += 1
        if not self.realtime:
            return
        lag = time.perf_counter() - self.t0 - self.scheduled * self.dt
        if lag > self.max_lag:  # a stall (the machine, a dragged window): no burst to catch up
            self.t0, self.scheduled = time.perf_counter(), 0
        else:
            time.sleep(max(0.0, -lag))

    @property
    def factor(self) -> float:
        wall = time.perf_counter() - self.start
        return self.steps * self.dt / wall if wall > 0 else float("nan")


class Stopped(KeyboardInterrupt):
    """A person session stopped from outside: Ctrl-C (``reason`` "interrupted") or SIGTERM
    ("terminated"). A KeyboardInterrupt, so whatever already handles Ctrl-C handles it too."""

    def __init__(self, reason: str = "interrupted") -> None:
        super().__init__(reason)
        self.reason = reason


def stop_reason(error: KeyboardInterrupt) -> str:
    """The ``end`` line's reason for an interrupt: SIGTERM's, or Ctrl-C's."""
    return error.reason if isinstance(error, Stopped) else "interrupted"


@contextlib.contextmanager
def sigterm_stops() -> Iterator[None]:
    """Within: SIGTERM raises :class:`Stopped` ("terminated") in the main thread, so the session
    writes its ``end`` line and exits as after Ctrl-C (status 130). Elsewhere than the main
    thread (no signal handler can be set there), nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: Any) -> None:
        raise Stopped("terminated")

    before = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


def ended_words(reason: str, sim_time: float) -> str:
    """The console's line on how a session ended."""
    return f"session ended: {reason}, after {sim_time:.1f} simulated s"
