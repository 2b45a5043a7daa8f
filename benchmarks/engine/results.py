"""A results folder: atomic per-unit records, meta.json, resume, and the long-format tables.

Layout::

    OUT/meta.json                   resolved config, config hash, seeds, the persons as used,
                                    versions, git, wall times
    OUT/records/<unit>.json         one file per finished unit of work (a block of run seeds ×
                                    every learner), written to a temp file, fsync'ed, os.replace'd
    OUT/runs.csv, curves.csv        per-run records in long format (rebuilt from records/)
    OUT/summary.csv, stats.csv, anova.csv, summary.md, plots/   (see report.py)

A record file exists completely or not at all, so after Ctrl-C or a crash the folder holds only
finished units; rerunning the same command runs the missing ones. Records are keyed by seed,
and each unit is a deterministic function of (config, seeds), so the final tables are the same
as those of an uninterrupted run. A folder made with another config, or one we cannot parse,
raises :class:`ResultsError` and is never overwritten unless the caller asks (``force``).
"""

from __future__ import annotations

import csv
import datetime as _dt
import math
import os
import shutil
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from strol_gym.benchmarks.engine.config import BenchConfig, Unit, diff_configs
from strol_gym.benchmarks.engine.kernels import float_kernels, kernel_label, mixed_kernels_message
from strol_gym.benchmarks.engine.lock import (
    BREAK,
    LOCK,
    LockError,
    clean_leftovers,
    hold_folder,
    release_folder,
)
from strol_gym.benchmarks.engine.record import REQUIRED_FIELDS, RUN_FIELDS, RunRecord
from strol_gym.files import loads_json, open_atomic, read_regular, write_json_atomic
from strol_gym.metrics import RUN_METRICS
from strol_gym.provenance import git_revision, package_versions, version_changes

META = "meta.json"
RECORDS = "records"
assert set(RUN_FIELDS) == set(RUN_METRICS), "runs.csv must hold every run metric"


class ResultsError(RuntimeError):
    """A results folder that cannot be used as asked: mismatched config, corrupt, or not ours."""


def _explain(diff: str) -> str:
    """Plain words for the non-obvious parts of a config difference."""
    if diff.startswith("extra.code:"):
        return "the strol-gym code (tasks, envs, humans, learners, weights, runner) has changed"
    if diff.startswith("extra.learners"):
        return f"a learner's class, settings or weights changed ({diff})"
    if diff.startswith("extra.numeric_packages"):
        return f"a numeric package version changed ({diff})"
    return diff


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


class ResultsDir:
    """A benchmark's results folder, bound to one config.

    ``open`` creates it or validates an existing one (same config hash: resume). Only the
    process that owns this object writes to the folder: workers return records to it.
    """

    def __init__(self, path: Path, config: BenchConfig, config_hash: str, meta: dict) -> None:
        self.path = path
        self.config = config
        self.config_hash = config_hash
        self.meta = meta

    # ------------------------------------------------------------------ open / create
    @classmethod
    def open(
        cls,
        path: str | os.PathLike,
        config: BenchConfig,
        *,
        extra: dict[str, Any] | None = None,
        force: bool = False,
    ) -> ResultsDir:
        """Create ``path`` for ``config`` or resume it; ``force`` replaces earlier results.

        ``extra`` joins the config in the hash (e.g. fingerprints of learner weights) and is
        stored in meta.json.
        """
        path = Path(path)
        try:
            rd = cls._open(path, config, extra, force)
        except OSError as e:
            raise ResultsError(
                f"--out {path}: cannot write the results folder there ({e.strerror or e})"
            ) from None
        return rd

    @classmethod
    def _open(
        cls, path: Path, config: BenchConfig, extra: dict[str, Any] | None, force: bool
    ) -> ResultsDir:
        chash = config.hash(extra)
        persons = config.persons()  # the command's own config: a person refused stops here
        meta_path = path / META
        if path.exists() and not path.is_dir():
            raise ResultsError(f"--out {path} exists and is not a folder")
        if path.exists() and any(path.iterdir()) and not cls._begun_by_a_gone_run(path, force):
            if not meta_path.exists():
                raise ResultsError(
                    f"{path} is not empty and has no {META}: it is not a strol-bench results "
                    "folder. Choose another --out; nothing was changed."
                )
            if force:
                cls._check_ours(path)
                _acquire_lock(path, force=True)  # never delete a folder a live run is writing
                for p in path.iterdir():  # everything but the lock we hold
                    if p.name != LOCK:
                        shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
            else:
                meta = cls._read_meta(path)
                cls._check_versions(path, meta)  # first: the plainest reason a hash differs
                if meta.get("config_hash") != chash:
                    diffs = diff_configs(meta.get("config", {}), config.to_dict())
                    diffs += diff_configs(meta.get("extra", {}), extra or {}, "extra")
                    diffs = [_explain(d) for d in diffs]
                    detail = "; ".join(diffs[:8]) or "config hash differs"
                    raise ResultsError(
                        f"{path} holds results of a different configuration ({detail}). "
                        "Use another --out, or --force to delete those results and start over."
                    )
                _acquire_lock(path)
                rd = cls(path, config, chash, meta)
                rd.warn_mixed_kernels()
                # A deleted records/ folder (or one lost otherwise) is recreated: its units
                # are simply missing and this run computes them again.
                (path / RECORDS).mkdir(exist_ok=True)
                return rd
        path.mkdir(parents=True, exist_ok=True)
        _acquire_lock(path)
        seeds = {
            f"{e.env}/{e.condition.name}": [e.seeds.start, e.seeds.stop - 1]
            for e in config.experiments
        }
        meta = {
            "tool": "strol-bench",
            "config": config.to_dict(),
            "config_hash": chash,
            "extra": extra or {},
            "seeds": seeds,
            "persons": persons,
            "created": _now(),
            "versions": package_versions(),
            "git": git_revision(),
            "kernels": float_kernels(),
            "sessions": [],
            "status": "running",
        }
        (path / RECORDS).mkdir(exist_ok=True)
        write_json_atomic(meta_path, meta)
        return cls(path, config, chash, meta)

    @staticmethod
    def _begun_by_a_gone_run(path: Path, force: bool) -> bool:
        """Whether ``path`` was begun by a run that is gone before it wrote its meta.json (only
        its lock, an empty records/ and temporary files are there): then this process holds it
        and creates it anew. A run still creating it is named (its lock), not called "not a
        results folder"."""
        if (path / META).exists() or not (path / LOCK).exists():
            return False
        _acquire_lock(path, force=force)  # a live run's: ResultsError naming it
        if (path / META).exists():
            return False  # finished by its creator meanwhile: resumed as any results folder
        records = path / RECORDS
        if any(p.name != LOCK for p in path.iterdir() if p != records) or (
            records.is_dir() and any(records.iterdir())
        ):
            _release_lock(path)
            return False
        return True

    @staticmethod
    def _read_meta(path: Path) -> dict:
        try:
            meta = loads_json(read_regular(path / META), str(path / META))
        except (OSError, ValueError) as e:  # ValueError: bad JSON, not UTF-8, nested too deep
            raise ResultsError(
                f"{path / META} is unreadable or corrupt ({type(e).__name__}: {e}). Use another "
                "--out, or --force to delete this folder's results and start over."
            ) from None
        if not isinstance(meta, dict) or meta.get("tool") != "strol-bench" or "config" not in meta:
            raise ResultsError(f"{path / META} is not a strol-bench meta file")
        for key, kind, word in (("config", dict, "object"), ("config_hash", str, "string")):
            if not isinstance(meta.get(key), kind):
                raise ResultsError(
                    f"{path / META}: {key!r} must be a JSON {word}, got {meta.get(key)!r:.60}; "
                    "use another --out, or --force to start over"
                )
        # Session bookkeeping only (wall times): a damaged list is repaired, not fatal.
        sessions = meta.get("sessions")
        meta["sessions"] = (
            [s for s in sessions if isinstance(s, dict)] if isinstance(sessions, list) else []
        )
        return meta

    @staticmethod
    def _check_versions(path: Path, meta: dict) -> None:
        """Warn (stderr) and refuse to resume a folder made under other versions of the packages
        that shape a record's bytes: its records and the new ones would not be one run's.
        ``--force`` (which starts the folder over) is the way past it."""
        recorded = meta.get("versions")
        changed = version_changes(recorded if isinstance(recorded, dict) else {})
        if not changed:
            return
        print(
            f"warning: {path} was made under other package versions ({'; '.join(changed)}); "
            "its means and verdicts would hold under these, its bytes only under the same "
            "versions (docs/reproducibility.md)",
            file=sys.stderr,
        )
        raise ResultsError(
            f"{path} was made under other package versions ({'; '.join(changed)}), so resuming "
            "it would mix records of two installs. Reinstall those versions (pip install -c "
            ".ci/constraints.txt ... for the lock), use another --out, or --force to delete its "
            "results and start over under these versions."
        )

    @staticmethod
    def _check_ours(path: Path) -> None:
        """Refuse to delete a folder holding anything but our own outputs."""
        ours = {META, RECORDS, "plots", "runs.csv", "curves.csv", "summary.csv", "stats.csv"}
        ours |= {"anova.csv", "summary.md", LOCK, BREAK, ".slurm"}
        foreign = [
            p.name
            for p in path.iterdir()
            if p.name not in ours and not (p.name.startswith(".") and p.name.endswith(".tmp"))
        ]
        if foreign:
            raise ResultsError(
                f"--force refused: {path} holds files strol-bench did not write: {foreign[:5]}"
            )

    @classmethod
    def load(cls, path: str | os.PathLike) -> ResultsDir:
        """Open an existing folder read-only-ish (for ``report``), trusting its meta.json."""
        path = Path(path)
        if not (path / META).exists():
            raise ResultsError(f"{path} has no {META}: not a strol-bench results folder")
        meta = cls._read_meta(path)
        try:
            config = BenchConfig.from_dict(meta["config"], trusted=False)
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise ResultsError(
                f"{path / META} has an invalid config ({type(e).__name__}: {e})"
            ) from None
        extra = meta.get("extra", {})
        if not isinstance(extra, dict) or config.hash(extra) != meta["config_hash"]:
            raise ResultsError(
                f"{path / META}: its config does not match its config_hash (the file was "
                "edited?); the tables would describe settings the runs did not use. Rerun the "
                "benchmark, or restore meta.json"
            )
        return cls(path, config, meta["config_hash"], meta)

    # ------------------------------------------------------------------ records
    def record_path(self, unit: Unit) -> Path:
        return self.path / RECORDS / f"{unit.key}.json"

    def done_keys(self) -> set[str]:
        """Keys of the units whose record file exists (validated when read)."""
        d = self.path / RECORDS
        if not d.exists():
            return set()
        return {p.stem for p in d.glob("*.json") if not p.name.startswith(".")}

    def missing_units(self) -> list[Unit]:
        done = self.done_keys()
        return [u for u in self.config.units() if u.key not in done]

    def write_unit(self, unit: Unit, records: Sequence[RunRecord]) -> None:
        """Store a finished unit atomically, with the kernels of the process that computed it
        (the workers stamp each record with ``kernels``; stored once per unit)."""
        labels = sorted({str(r["kernels"]) for r in records if "kernels" in r})
        payload = {
            "config_hash": self.config_hash,
            "unit": {"experiment": unit.experiment, "seeds": list(unit.seeds)},
            "kernels": "; ".join(labels) or None,
            "records": [{k: v for k, v in r.items() if k != "kernels"} for r in records],
        }
        write_json_atomic(self.record_path(unit), payload)

    def kernels_by_unit(self) -> dict[str, list[str]]:
        """Unit keys grouped by the kernels their records were computed with ("unrecorded" for
        records written before kernels were recorded, "unreadable" for a corrupt file)."""
        out: dict[str, list[str]] = {}
        for p in sorted((self.path / RECORDS).glob("*.json")):
            if p.name.startswith("."):
                continue
            try:
                label = loads_json(read_regular(p), str(p)).get("kernels") or "unrecorded"
            except (OSError, ValueError, AttributeError):
                label = "unreadable"
            out.setdefault(str(label), []).append(p.stem)
        return out

    def warn_mixed_kernels(self) -> str | None:
        """Print (stderr) and return one line if the records came from other kernels than this
        process's, or from several."""
        msg = mixed_kernels_message(self.path, self.kernels_by_unit(), kernel_label())
        if msg:
            print(msg, file=sys.stderr)
        return msg

    def read_records(self) -> list[RunRecord]:
        """Every record, validated, in canonical order (experiment, seed, learner order)."""
        units = {u.key: u for u in self.config.units()}
        out: list[RunRecord] = []
        nan_seen: dict[tuple[int, str], dict[bool, tuple[Path, dict]]] = {}
        for p in sorted((self.path / RECORDS).glob("*.json")):
            if p.name.startswith("."):
                continue
            unit = units.get(p.stem)
            if unit is None:
                raise ResultsError(f"{p} does not belong to this config's units: corrupt folder")
            try:
                payload = loads_json(read_regular(p), str(p))
                ok = payload["config_hash"] == self.config_hash
                recs = payload["records"]
                seeds = tuple(payload["unit"]["seeds"])
            except (OSError, ValueError, KeyError, TypeError) as e:  # ValueError: not UTF-8/JSON
                raise ResultsError(f"{p} is corrupt ({e}); delete it to rerun that unit") from e
            if not ok:
                raise ResultsError(f"{p} was written by another config (hash differs)")
            expected = {(s, learner) for s in unit.seeds for learner in self.config.learners}
            if (
                not isinstance(recs, list)
                or not all(isinstance(r, dict) for r in recs)
                or not all(isinstance(s, int) for s in seeds)
            ):
                raise ResultsError(f"{p} is corrupt (records must be a list of objects)")
            exp = self.config.experiments[unit.experiment]
            for r in recs:
                _check_record(p, r, exp.env, exp.condition.name, exp.corrections)
                for key in RUN_FIELDS:  # NaN: legitimate only for a whole experiment
                    nan_seen.setdefault((unit.experiment, key), {})[math.isnan(r[key])] = (p, r)
            got = [(r.get("seed"), r.get("learner")) for r in recs]
            where = {(r.get("env"), r.get("condition")) for r in recs}
            if seeds != unit.seeds or len(got) != len(expected) or set(got) != expected:
                raise ResultsError(f"{p} does not hold exactly its unit's runs; delete it to rerun")
            if where != {(exp.env, exp.condition.name)}:
                raise ResultsError(f"{p} holds runs of another env or condition than its unit's")
            out.extend(recs)
        for (_, name), seen in nan_seen.items():
            if len(seen) > 1:  # some runs have it and some do not: an edited or broken record
                p, r = seen[True]
                raise ResultsError(
                    f"{p}: run seed {r['seed']!r}, learner {r['learner']!r}: {name!r} is NaN while "
                    "other runs of its experiment have it (NaN is only for an env that does not "
                    "score it, e.g. regret without a planner); delete the file to rerun its unit"
                )
        order = {learner: i for i, learner in enumerate(self.config.learners)}
        exp_index = {(e.env, e.condition.name): i for i, e in enumerate(self.config.experiments)}
        out.sort(
            key=lambda r: (exp_index[(r["env"], r["condition"])], r["seed"], order[r["learner"]])
        )
        return out

    def finish_session(self, started: str, wall_time_s: float, units_run: int, jobs: int) -> None:
        """Append this session's wall time to meta.json, mark the folder complete if it is, and
        release the folder's lock. "complete" means every unit's record is there and valid; a
        corrupt one leaves the folder "incomplete" (``read_records`` names it)."""
        try:
            sessions = self.meta.get("sessions")
            if not isinstance(sessions, list):
                sessions = self.meta["sessions"] = []
            sessions.append(
                {
                    "started": started,
                    "wall_time_s": wall_time_s,
                    "units_run": units_run,
                    "jobs": jobs,
                    "kernels": kernel_label(),
                }
            )
            by_label = self.kernels_by_unit()
            self.meta["record_kernels"] = {k: len(v) for k, v in by_label.items()}
            if len(by_label) > 1:  # e.g. Ray workers on different CPUs within this session
                self.warn_mixed_kernels()
            complete = not self.missing_units()
            if complete:
                try:
                    self.read_records()
                except ResultsError:
                    complete = False
            self.meta["status"] = "complete" if complete else "incomplete"
            self.meta["wall_time_s"] = sum(
                float(s.get("wall_time_s") or 0.0) for s in sessions if isinstance(s, dict)
            )
            write_json_atomic(self.path / META, self.meta)
        finally:
            _release_lock(self.path)

    # ------------------------------------------------------------------ long-format tables
    def write_run_tables(self, records: Sequence[RunRecord]) -> tuple[Path, Path]:
        """runs.csv (one row per run × learner) and curves.csv (one row per step)."""
        runs_path, curves_path = self.path / "runs.csv", self.path / "curves.csv"
        max_steps = max((len(r["errors"]) for r in records), default=0)
        head = ["env", "condition", "learner", "seed", *RUN_FIELDS, "steps", "terminated"]
        head += [f"error_step_{k}" for k in range(max_steps)]
        with open_atomic(runs_path, newline="") as f:
            w = csv.writer(f)
            w.writerow(head)
            for r in records:
                errs = list(r["errors"]) + [math.nan] * (max_steps - len(r["errors"]))
                w.writerow(
                    [r["env"], r["condition"], r["learner"], r["seed"]]
                    + [_fmt(r[k]) for k in RUN_FIELDS]
                    + [r["steps"], int(bool(r["terminated"]))]
                    + [_fmt(e) for e in errs]
                )
        with open_atomic(curves_path, newline="") as f:
            w = csv.writer(f)
            w.writerow(["env", "condition", "learner", "seed", "step", "error", "cos_error"])
            for r in records:
                for k, (e, c) in enumerate(zip(r["errors"], r["cos_errors"], strict=True)):
                    w.writerow(
                        [r["env"], r["condition"], r["learner"], r["seed"], k, _fmt(e), _fmt(c)]
                    )
        return runs_path, curves_path


def _check_record(p: Path, r: dict, env: str, condition: str, corrections: int) -> None:
    """One run's record as the runner writes it, or ResultsError naming the file, the run and
    the field: a missing or non-finite value is named, never dropped from the tables."""
    who = f"{p}: run seed {r.get('seed')!r}, learner {r.get('learner')!r}"
    rerun = "; delete the file to rerun its unit"
    for key in REQUIRED_FIELDS:
        if key not in r:
            raise ResultsError(f"{who}: {key!r} is missing{rerun}")
    if r["env"] != env or r["condition"] != condition:
        raise ResultsError(
            f"{who}: env/condition {r['env']!r}/{r['condition']!r} is not its unit's "
            f"{env!r}/{condition!r}{rerun}"
        )
    steps = r["steps"]
    if type(steps) is not int or not 0 <= steps <= corrections:
        raise ResultsError(
            f"{who}: 'steps' must be an integer in [0, {corrections}], got {steps!r}"
        )
    for key in RUN_FIELDS:  # NaN is checked across the experiment by read_records
        v = r.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or math.isinf(v):
            raise ResultsError(f"{who}: {key!r} must be a finite number, got {v!r}{rerun}")
    for key in ("errors", "cos_errors"):
        seq = r.get(key)
        if not isinstance(seq, list) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and not math.isinf(v)
            for v in seq
        ):
            raise ResultsError(f"{who}: {key!r} must be a list of numbers (no inf){rerun}")
    if len(r["cos_errors"]) != len(r["errors"]):
        raise ResultsError(f"{who}: 'errors' and 'cos_errors' differ in length{rerun}")


def _acquire_lock(path: Path, force: bool = False) -> None:
    """Hold ``path``'s lock (see ``engine.lock``) and clean what dead writers left behind."""
    try:
        hold_folder(path, force=force)
    except LockError as e:
        raise ResultsError(str(e)) from None
    clean_leftovers(path)
    clean_leftovers(path / RECORDS)


def _release_lock(path: Path) -> None:
    """Remove ``path``'s lock if this process holds it."""
    release_folder(path)


def _fmt(x: Any) -> str:
    """Full-precision text for CSV (repr round-trips floats exactly)."""
    if x is None:
        return "nan"
    return repr(float(x))


def write_csv(path: Path, rows: Iterable[dict], columns: Sequence[str]) -> Path:
    """Write dict rows with the given column order; floats at full precision."""
    with open_atomic(path, newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for r in rows:
            w.writerow([_cell(r.get(c)) for c in columns])
    return path


def _cell(v: Any) -> str:
    """A CSV cell: numpy scalars as the Python numbers they hold (numpy 2's repr would write
    ``np.float64(2.2)``), floats at full precision, booleans lower-case, None empty."""
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, float):
        return repr(v)
    return "" if v is None else str(v)
