"""What the page may send, checked before anything else sees it.

Nothing from a page is trusted: a message is a JSON object of at most :data:`MAX_MESSAGE`
bytes, nested at most :data:`MAX_DEPTH` deep, of one of two kinds, with every field bounded::

    {"t": "start"}                                   begin the next session
    {"t": "input", "n": 17, "keys": ["w", "shift"],  the keys held now (names the mapping knows)
     "pad": {"axes": [...], "buttons": [...]}}       and a gamepad (or null)

Anything else is :class:`Refused` with a short reason the page is told; no field is a path or
code, and key names outside the shared mapping (:mod:`strol_gym.benchmarks.sessions.keys`) are
refused, not ignored. :class:`RateLimit` caps how many messages a connection may send.
"""

from __future__ import annotations

import math
import time
from typing import Any

from strol_gym.benchmarks.sessions import keys as keymap
from strol_gym.files import loads_json

MAX_MESSAGE = 1024
"""Bytes in one message from a page (a full gamepad and every key fit in about 400)."""
MAX_DEPTH = 4
MAX_KEYS = 12
MAX_AXES, MAX_BUTTONS = 8, 20
MAX_SEQUENCE = 2**31 - 1
KNOWN_KEYS = frozenset(keymap.ARM_KEYS) | frozenset(keymap.CAR_KEYS) | {keymap.HARDER_KEY}
"""Key names a page may report held: the shared mapping's."""


class Refused(ValueError):
    """A message the server will not act on; the text says why (it goes back to the page)."""


def _numbers(what: str, value: Any, most: int, low: float, high: float) -> list[float]:
    if not isinstance(value, list) or len(value) > most:
        raise Refused(f"{what} must be a list of at most {most} numbers")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise Refused(f"{what} must hold finite numbers")
        if not low <= v <= high:
            raise Refused(f"{what} must lie in [{low:g}, {high:g}]")
        out.append(float(v))
    return out


def parse(message: str | bytes | None) -> dict[str, Any]:
    """The checked message (a new dict holding only known fields) or :class:`Refused`."""
    if message is None:
        raise Refused("a message must be text (JSON)")
    size = len(message.encode() if isinstance(message, str) else message)
    if size > MAX_MESSAGE:
        raise Refused(f"a message has at most {MAX_MESSAGE} bytes, got {size}")
    try:
        raw = loads_json(message, "the message", max_depth=MAX_DEPTH)
    except ValueError as e:
        raise Refused(str(e)) from None
    if not isinstance(raw, dict):
        raise Refused("a message must be a JSON object")
    kind = raw.get("t")
    if kind == "start" and set(raw) == {"t"}:
        return {"t": "start"}
    if kind != "input":
        raise Refused('a message\'s "t" must be "start" or "input"')
    extra = set(raw) - {"t", "n", "keys", "pad"}
    if extra:
        raise Refused(f"unknown field(s) {sorted(extra)[:3]}")
    n = raw.get("n")
    if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= MAX_SEQUENCE:
        raise Refused(f'"n" must be an integer in [0, {MAX_SEQUENCE}]')
    held = raw.get("keys")
    if not isinstance(held, list) or len(held) > MAX_KEYS:
        raise Refused(f'"keys" must be a list of at most {MAX_KEYS} key names')
    names = []
    for k in held:
        if not isinstance(k, str) or keymap.key_name(k) not in KNOWN_KEYS:
            raise Refused(f'"keys" holds {str(k)[:20]!r}, not a key of the mapping')
        names.append(keymap.key_name(k))
    pad = raw.get("pad")
    if pad is not None:
        if not isinstance(pad, dict) or set(pad) != {"axes", "buttons"}:
            raise Refused('"pad" must be null or {"axes": [...], "buttons": [...]}')
        pad = {
            "axes": _numbers('"pad.axes"', pad["axes"], MAX_AXES, -1.0, 1.0),
            "buttons": _numbers('"pad.buttons"', pad["buttons"], MAX_BUTTONS, 0.0, 1.0),
        }
    return {"t": "input", "n": n, "keys": sorted(set(names)), "pad": pad}


class RateLimit:
    """A token bucket: ``rate`` messages a second on average, ``burst`` at once."""

    def __init__(self, rate: float = 60.0, burst: float = 60.0) -> None:
        self.rate, self.burst = rate, burst
        self.tokens = burst
        self.last = time.monotonic()

    def allow(self) -> bool:
        now = time.monotonic()
        self.tokens = min(self.burst, self.tokens + (now - self.last) * self.rate)
        self.last = now
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return True
        return False


__all__ = ["KNOWN_KEYS", "MAX_MESSAGE", "RateLimit", "Refused", "parse"]
