"""The results folder's lock: one process at a time plans and collects into a folder.

Why this shape. The lock must hold on one machine, between machines that share a file system
(a Slurm cluster over NFS, where pids repeat across hosts and ``flock`` is unreliable) and
after a crash:

- **Written whole before it counts.** The lock's text (host, pid, the process's start time) is
  written to a temporary file named for this host and pid, fsync'ed, then ``os.link``'ed to
  ``.lock``. A link fails if ``.lock`` exists, so exactly one process wins, and nobody ever
  reads a half-written lock (an empty lock read as "pid 0, gone" let two runs in).
- **Stale only when provably gone**: written on this host (and this boot) by a process that no
  longer runs, or whose pid now belongs to a process started at another time (a recycled pid).
  A lock from another host is never taken over unless the caller forces it (``--force``).
- **Taking over a stale lock is itself exclusive**: the taker first links ``.lock.break``
  (the same way), checks that ``.lock`` is still the very file it judged stale (same inode
  and bytes), and only then replaces it. Two processes that both find a stale lock cannot
  both take it over.

Only the process that plans and collects holds the lock (under Ray and Slurm too); workers
return records to it, or write uniquely named files atomically, and never take it.
:func:`temp_tag` names temporary files by host and pid so that leftovers can be told apart
and cleaned (:func:`clean_leftovers`) by the next holder.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from strol_gym.files import host, open_regular, temp_tag

LOCK = ".lock"
BREAK = ".lock.break"
_MAX_LOCK_BYTES = 4096  # a lock is one short JSON line; anything larger is not ours
_WRITE_HOOK: list = []  # tests only: callables run between a temp lock's creation and its link


class LockError(RuntimeError):
    """The folder is held by another run (or its lock cannot be judged)."""


def _boot_id() -> str | None:
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip() or None
    except OSError:
        return None


def start_time(pid: int) -> int | None:
    """The process's start time in clock ticks since boot (Linux), or None where unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    try:  # the command name (field 2) may hold spaces and parentheses: split after the last ')'
        return int(stat[stat.rindex(")") + 2 :].split()[19])
    except (ValueError, IndexError):
        return None


@dataclass(frozen=True)
class Owner:
    """Who holds a lock: host, pid, the process's start time and the host's boot."""

    host: str
    pid: int
    start: int | None
    boot: str | None

    @classmethod
    def me(cls) -> Owner:
        return cls(host(), os.getpid(), start_time(os.getpid()), _boot_id())

    def text(self) -> str:
        return json.dumps(
            {"host": self.host, "pid": self.pid, "start": self.start, "boot": self.boot}
        )

    @classmethod
    def parse(cls, text: str) -> Owner | None:
        """The owner in a lock's text; a bare pid (the old format) counts as this host's."""
        text = text.strip()
        if text.isdigit():
            return cls(host(), int(text), None, None)
        try:
            d = json.loads(text)
        except (ValueError, RecursionError):
            return None
        if not (
            isinstance(d, dict)
            and isinstance(d.get("host"), str)
            and type(d.get("pid")) is int
            and d["pid"] > 0
            and (d.get("start") is None or type(d.get("start")) is int)
            and (d.get("boot") is None or isinstance(d.get("boot"), str))
        ):
            return None
        return cls(d["host"], d["pid"], d.get("start"), d.get("boot"))

    def gone(self) -> bool:
        """True only if this lock was written on this host by a process that no longer runs."""
        if self.host != host():
            return False
        mine = _boot_id()
        if self.boot is not None and mine is not None and self.boot != mine:
            return True  # written before this host rebooted
        if not _pid_alive(self.pid):
            return True
        if self.start is None and not _may_be_ours(self.pid):
            return True  # no start time to compare (a bare pid): the process there is not ours
        now = start_time(self.pid)
        return self.start is not None and now is not None and now != self.start  # recycled

    def words(self) -> str:
        return f"host {self.host}, pid {self.pid}"


def _may_be_ours(pid: int) -> bool:
    """Whether the process ``pid`` may be a strol-bench run: a Python interpreter or
    strol-bench by its command line (pid 1 is init on most hosts); True where /proc cannot
    say (no /proc, or an empty command line: a process between fork and exec)."""
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes()[:4096].lower()
    except OSError:
        return True
    return not cmd or b"python" in cmd or b"strol" in cmd


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, owned by someone else
        return True
    return True


def _read(lock: Path) -> tuple[Owner | None, os.stat_result, bytes] | None:
    """The lock's owner, stat and bytes; None if it does not exist."""
    try:
        with open_regular(lock, "lock file") as f:
            st = os.fstat(f.fileno())
            data = f.read(_MAX_LOCK_BYTES + 1)
    except FileNotFoundError:
        return None
    if len(data) > _MAX_LOCK_BYTES:
        return None, st, data
    try:
        return Owner.parse(data.decode("utf-8")), st, data
    except UnicodeDecodeError:
        return None, st, data


def _link_new(target: Path, owner: Owner) -> bool:
    """Write ``owner`` whole to a temp file named for this host and pid, then link it to
    ``target``; False if ``target`` exists."""
    tmp = target.with_name(f"{target.name}.{temp_tag()}.tmp")
    try:
        with open(tmp, "w") as f:
            for hook in _WRITE_HOOK:
                hook()
            f.write(owner.text() + "\n")
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(tmp, target)
        except FileExistsError:
            return False
        return True
    finally:
        tmp.unlink(missing_ok=True)


def _same(lock: Path, st: os.stat_result, data: bytes) -> bool:
    now = _read(lock)
    return now is not None and now[1].st_ino == st.st_ino and now[2] == data


def hold_folder(path: str | os.PathLike, *, force: bool = False, what: str = "--out") -> Owner:
    """Take ``path``'s lock for this process, or raise :class:`LockError` naming its holder.

    A stale lock (this host, its process gone or its pid recycled) is taken over with a note
    on stderr. ``force`` also takes over another host's lock (the user says that run is gone);
    a live process on this host is never displaced. Holding it again is a no-op.
    """
    path = Path(path)
    lock, me = path / LOCK, Owner.me()
    for _ in range(50):
        if _link_new(lock, me):
            return me
        seen = _read(lock)
        if seen is None:
            continue  # released between our link and our read: try again
        owner, st, data = seen
        if owner is not None and owner.host == me.host and owner.pid == me.pid:
            if owner.start == me.start or owner.start is None:
                return me  # already ours
        if owner is None:
            raise LockError(
                f"{lock} is not a strol-bench lock (unreadable); if no run uses {path}, "
                f"delete {lock} and rerun"
            )
        if not owner.gone() and not (force and owner.host != me.host):
            if owner.host != me.host:
                raise LockError(
                    f"{path} is in use by another strol-bench run ({owner.words()}, lock file "
                    f"{lock}); if that run is gone, rerun with --force to take it over"
                )
            raise LockError(
                f"{path} is in use by another strol-bench run ({owner.words()}, lock file "
                f"{lock}); wait for it to finish or use another {what}"
            )
        if _take_over(path, st, data, me):
            why = "forced" if not owner.gone() else "the run that held it is gone"
            print(f"note: took over {lock} ({owner.words()}): {why}", file=sys.stderr)
            return me
        time.sleep(0.01)
    raise LockError(f"{path}: could not take the lock file {lock} (other runs keep taking it)")


def _take_over(path: Path, st: os.stat_result, data: bytes, me: Owner) -> bool:
    """Replace the lock we judged stale, if it still is that very file; exclusive."""
    brk, lock = path / BREAK, path / LOCK
    if not _link_new(brk, me):
        held = _read(brk)  # another taker; its own lock is stale only if it died mid-takeover
        if held is not None and held[0] is not None and held[0].gone():
            with contextlib.suppress(OSError):
                if _same(brk, held[1], held[2]):
                    brk.unlink()
        return False
    try:
        if not _same(lock, st, data):
            return False  # released or replaced since we looked: judge again
        lock.unlink()
        return _link_new(lock, me)
    finally:
        brk.unlink(missing_ok=True)


def release_folder(path: str | os.PathLike) -> None:
    """Remove ``path``'s lock if this process holds it (a no-op otherwise)."""
    lock = Path(path) / LOCK
    seen = _read(lock)
    if seen is None or seen[0] is None:
        return
    owner, me = seen[0], Owner.me()
    if owner.host == me.host and owner.pid == me.pid:
        with contextlib.suppress(OSError):
            lock.unlink()


@contextlib.contextmanager
def holding(path: str | os.PathLike, *, force: bool = False) -> Iterator[Owner]:
    """``hold_folder`` for a with-block."""
    owner = hold_folder(path, force=force)
    try:
        yield owner
    finally:
        release_folder(path)


def clean_leftovers(folder: str | os.PathLike) -> list[Path]:
    """Remove temporary files (``.NAME.HOST-PID….tmp``) that this host's gone processes left
    in ``folder`` (a SIGKILL mid-write); call it while holding the lock. Other hosts' temps
    are left alone (their writers may still run)."""
    removed = []
    me = host()
    for p in Path(folder).glob(".*.tmp"):
        pid = _tag_pid(p.name, me)
        if pid is not None and (pid != os.getpid()) and not _pid_alive(pid):
            with contextlib.suppress(OSError):
                p.unlink()
                removed.append(p)
    return removed


def _tag_pid(name: str, me: str) -> int | None:
    """The pid in a temp file's name written on host ``me``, else None."""
    marker = f".{me}-"
    i = name.rfind(marker)
    if i < 0:
        return None
    digits = ""
    for c in name[i + len(marker) :]:
        if not c.isdigit():
            break
        digits += c
    return int(digits) if digits else None
