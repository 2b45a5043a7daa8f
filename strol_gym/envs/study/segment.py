"""Where a correction begins and ends: a small state machine fed the felt force once per step.

A person's push does not stay above the threshold from first touch to release: a hand
regrips, a mouse drag's force jitters, a push eases off and comes back. Ending the correction
at the first step below the threshold (the published study's rule, StROL-Study-v0/v1) cut one
xdotool mouse drag into 13 single-step corrections. With a **hold-off** a correction ends only
once the felt force has stayed at or below the threshold for that long; a push that comes back
within it continues the same correction. A hold-off of 0 is the published rule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

Phase = Literal["idle", "pushing", "holding"]
"""``idle``: no correction; ``pushing``: the felt force is above the threshold; ``holding``:
a correction whose force has dropped, waiting out the hold-off."""
Event = Literal["start", "release", "end"] | None

HOLD_OFF_RANGE = (0.0, 0.5)
"""Hold-offs accepted (s): 0 is the published rule; beyond 0.5 s two deliberate pushes would
merge and the learner would wait long after a release (issue 36)."""


@dataclass
class PushSegmenter:
    """Segments the felt force into corrections, one control step at a time.

    ``hold_steps``: the control steps the force must stay at or below the threshold before
    the correction ends (0: it ends at the first such step).
    """

    threshold: float
    hold_steps: int = 0
    phase: Phase = "idle"
    below: int = 0
    """Steps the force has been at or below the threshold within the current correction."""

    @classmethod
    def for_hold_off(cls, threshold: float, hold_off: float, dt: float) -> PushSegmenter:
        """A segmenter whose hold-off is ``hold_off`` seconds of steps of ``dt`` seconds."""
        return cls(threshold, math.ceil(hold_off / dt - 1e-9))

    @property
    def active(self) -> bool:
        """A correction is under way (pushing or holding)."""
        return self.phase != "idle"

    def feed(self, felt: float, can_push: bool = True) -> Event:
        """The step's felt force (N); ``can_push`` False (the arm braked) counts as no push.
        Returns "start" on the step a correction begins, "release" on a step its force drops
        to or below the threshold and the hold-off begins, "end" on the step it ends."""
        pushing = felt > self.threshold and can_push
        if pushing:
            self.below = 0
            started = self.phase == "idle"
            self.phase = "pushing"
            return "start" if started else None
        if self.phase == "idle":
            return None
        if self.below >= self.hold_steps:
            self.cancel()
            return "end"
        self.below += 1
        released = self.phase == "pushing"
        self.phase = "holding"
        return "release" if released else None

    def cancel(self) -> None:
        """Forget the correction under way (a reflex: a shove is no correction)."""
        self.phase, self.below = "idle", 0


__all__ = ["HOLD_OFF_RANGE", "Event", "Phase", "PushSegmenter"]
