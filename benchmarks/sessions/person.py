"""What both person modes of ``strol-bench interact`` share (the arm, ``interact``; the car,
``drive``): the wall-clock pace of the physics and the default log path."""

from __future__ import annotations

import datetime as dt
import time
from pathlib import Path


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
