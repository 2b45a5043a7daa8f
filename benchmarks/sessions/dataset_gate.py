"""The gate a Minari dataset passes before Minari sees its folder: reading data never runs code.

Minari rebuilds an env from a dataset's ``env_spec`` when a space is missing from its
``data/metadata.json``, and ``recover_environment()`` always does: ``gym.make`` then imports and
calls the spec's ``entry_point`` (and every ``additional_wrappers`` entry point) with the
spec's kwargs. So :func:`check_metadata` reads the file itself and accepts it only when

- ``observation_space`` and ``action_space`` are there (Box, Discrete or Dict of them, of a
  bounded size), so Minari never builds an env to learn them;
- ``env_spec`` and ``eval_env_spec`` are absent, or name an env id strol-gym registers with its
  ``entry_point`` and ``vector_entry_point`` equal, string for string, to the registered ones,
  wrappers from :data:`WRAPPERS` only (what our export writes), and kwargs holding no
  ``"module:attr"`` (a registered name is never one, so every piece is looked up by name).

Anything else is a :class:`DatasetRefused` naming the file. :func:`dataset_path` confines a
dataset id to the datasets root before anything is created there.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from strol_gym.files import NotAFile, check_input, read_regular
from strol_gym.limits import CAPS, check_size, lifted_now
from strol_gym.wrappers.session_log import SessionLogError

METADATA = "metadata.json"
MAX_METADATA_BYTES = 64 * 2**20
"""A dataset's metadata is a few kB (the header is one line of it); larger is not ours."""
MAX_SPACE_SIZE = 1_000_000
"""The most numbers a Box of a dataset's space may hold (ours hold tens)."""
ENV_SPEC_KEYS = {"id", "entry_point", "vector_entry_point", "kwargs", "additional_wrappers"}
ENV_SPEC_KEYS |= {"reward_threshold", "nondeterministic", "max_episode_steps", "order_enforce"}
ENV_SPEC_KEYS |= {"disable_env_checker", "apply_api_compatibility", "autoreset"}
MINARI_DROPS = (
    '"order_enforce": true,',
    '"apply_api_compatibility": false,',
    '"autoreset": false, ',
)
"""What Minari cuts from an env spec before parsing it: the gate parses what Minari parses."""
_PART = r"[A-Za-z0-9_][A-Za-z0-9_-]*"
DATASET_ID = re.compile(rf"^(?:{_PART}/)*{_PART}-v[0-9]+$")
"""Minari's ``(namespace/)name-vN``, with parts of letters, digits, ``_`` and ``-`` only: no
``..``, no absolute path, no empty part, so the id stays inside the datasets root."""


class DatasetRefused(SessionLogError):
    """A dataset (or dataset id) this project will not hand to Minari; names the file or id."""


def wrappers() -> dict[str, str]:
    """Wrapper name -> entry point: the wrappers an exported ``env_spec`` may carry."""
    from strol_gym.wrappers.online_learning import OnlineLearningWrapper

    cls = OnlineLearningWrapper
    return {cls.__name__: f"{cls.__module__}:{cls.__qualname__}"}


def registered_envs() -> dict[str, dict[str, Any]]:
    """Env id -> its registration (entry points): the ids an ``env_spec`` may name."""
    from strol_gym.registration import ENV_SPECS

    return ENV_SPECS


def datasets_root() -> Path:
    """Where Minari keeps datasets (``MINARI_DATASETS_PATH``, else ``~/.minari/datasets``)."""
    root = os.environ.get("MINARI_DATASETS_PATH")
    return Path(root) if root else Path.home() / ".minari" / "datasets"


def dataset_path(dataset_id: Any) -> Path:
    """The folder of ``dataset_id`` under :func:`datasets_root`; creates nothing."""
    if not isinstance(dataset_id, str) or len(dataset_id) > 200 or not DATASET_ID.match(dataset_id):
        raise DatasetRefused(
            f"dataset_id must look like namespace/name-vN (parts of letters, digits, '_' and "
            f"'-'; no '..', absolute path or empty part), got {dataset_id!r:.80}"
        )
    return datasets_root() / dataset_id


def _number_list(value: Any, n: int) -> bool:
    flat: list = []
    stack = [value]
    while stack:  # nested lists of numbers (or inf/nan strings Minari never writes: refused)
        v = stack.pop()
        if isinstance(v, list):
            if len(flat) + len(v) > MAX_SPACE_SIZE:
                return False
            stack.extend(v)
        elif isinstance(v, bool) or not isinstance(v, int | float):
            return False
        else:
            flat.append(v)
    return len(flat) == n


def _space(where: str, value: Any, depth: int = 0) -> None:
    """A serialized space Minari can rebuild without an allocation we have not sized."""
    if depth > 8 or not isinstance(value, dict):
        raise DatasetRefused(f"{where} must be a serialized space (an object)")
    kind = value.get("type")
    if kind == "Dict":
        subs = value.get("subspaces")
        if not isinstance(subs, dict) or not subs or len(subs) > 64:
            raise DatasetRefused(f"{where}: a Dict space needs 1 to 64 subspaces")
        for key, sub in subs.items():
            _space(f"{where}[{key!r}]", sub, depth + 1)
    elif kind == "Box":
        shape: Any = value.get("shape")  # untrusted JSON, checked here
        ok = isinstance(shape, list) and len(shape) <= 8
        ok = ok and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape)
        size = math.prod(shape) if ok else 0
        ok = ok and size <= MAX_SPACE_SIZE and value.get("dtype") in ("float32", "float64")
        ok = ok and all(_number_list(value.get(b), size) for b in ("low", "high"))
        if not ok:
            raise DatasetRefused(
                f"{where}: a Box needs a float dtype and a shape of at most {MAX_SPACE_SIZE} "
                "numbers, with low and high of that size"
            )
    elif kind == "Discrete":
        n: Any = value.get("n")  # untrusted JSON, checked here
        start: Any = value.get("start", 0)
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in (n, start)) or n < 1:
            raise DatasetRefused(f"{where}: a Discrete space needs integers n >= 1 and start")
    else:
        raise DatasetRefused(f"{where}: space type {kind!r} is not one of Box, Discrete, Dict")


def _module_names(where: str, value: Any, depth: int = 0) -> None:
    """Refuse any string naming ``module:attr`` inside kwargs (pieces are looked up by name)."""
    if depth > 16:
        raise DatasetRefused(f"{where} is nested too deeply")
    if isinstance(value, str) and ":" in value:
        raise DatasetRefused(
            f"{where} is {value!r:.80}: kwargs may name registered pieces only, not module:attr"
        )
    if isinstance(value, dict):
        for k, v in value.items():
            _module_names(f"{where}[{k!r}]", k, depth + 1)
            _module_names(f"{where}[{k!r}]", v, depth + 1)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _module_names(f"{where}[{i}]", v, depth + 1)


def check_env_spec(where: str, text: Any) -> dict[str, Any]:
    """An ``env_spec`` (JSON text) that names strol-gym's own env and wrappers only, parsed."""
    try:  # the text as Minari parses it (it drops these keys for gymnasium 1.0)
        for old in MINARI_DROPS:
            text = text.replace(old, "")
        spec = json.loads(text)
    except (AttributeError, ValueError, RecursionError):
        spec = None
    if not isinstance(spec, dict):
        raise DatasetRefused(f"{where} must be an env spec (a JSON object in a string)")
    unknown = sorted(set(spec) - ENV_SPEC_KEYS)
    if unknown:
        raise DatasetRefused(f"{where}: unknown keys {unknown[:5]}")
    envs = registered_envs()
    env_id = spec.get("id")
    if env_id not in envs:
        raise DatasetRefused(
            f"{where}: id {env_id!r:.80} is not an env strol-gym registers ({', '.join(envs)})"
        )
    registered = envs[env_id]
    for key in ("entry_point", "vector_entry_point"):
        if spec.get(key) != registered.get(key):
            raise DatasetRefused(
                f"{where}: {key} {spec.get(key)!r:.80} is not {env_id}'s ({registered.get(key)!r})"
            )
    _module_names(f"{where}: kwargs", spec.get("kwargs") or {})
    if not isinstance(spec.get("kwargs") or {}, dict):
        raise DatasetRefused(f"{where}: kwargs must be an object")
    ours: Mapping[Any, str] = wrappers()  # looked up by names from the file
    wrapper_specs = spec.get("additional_wrappers") or []
    if not isinstance(wrapper_specs, list):
        raise DatasetRefused(f"{where}: additional_wrappers must be a list")
    for i, w in enumerate(wrapper_specs):
        at = f"{where}: additional_wrappers[{i}]"
        if not isinstance(w, dict) or set(w) - {"name", "entry_point", "kwargs"}:
            raise DatasetRefused(f"{at} must be an object with name, entry_point and kwargs")
        if ours.get(w.get("name")) != w.get("entry_point"):
            raise DatasetRefused(
                f"{at}: entry_point {w.get('entry_point')!r:.80} is not one of strol-gym's "
                f"wrappers ({', '.join(ours.values())})"
            )
        if not isinstance(w.get("kwargs") or {}, dict):
            raise DatasetRefused(f"{at}: kwargs must be an object")
        _module_names(f"{at}.kwargs", w.get("kwargs") or {})
    steps = spec.get("max_episode_steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise DatasetRefused(f"{where}: max_episode_steps must be a positive integer or null")
    return spec


def read_metadata(path: str | Path) -> dict[str, Any]:
    """A Minari ``metadata.json`` as a dict, size-checked; :class:`DatasetRefused` names it."""
    path = Path(path)
    try:
        raw = read_regular(path, MAX_METADATA_BYTES, "Minari metadata file")
    except (OSError, ValueError) as e:  # NotAFile (a FIFO, a device), too large, unreadable
        raise DatasetRefused(f"{path}: {e}" if str(path) not in str(e) else str(e)) from None
    try:
        meta = json.loads(raw.decode("utf-8"))
    except (ValueError, RecursionError) as e:  # ValueError: not UTF-8 or not JSON
        raise DatasetRefused(f"{path}: not a Minari metadata file ({type(e).__name__})") from None
    if not isinstance(meta, dict):
        raise DatasetRefused(f"{path}: not a Minari metadata file (not a JSON object)")
    return meta


def check_metadata(path: str | Path) -> dict[str, Any]:
    """The gate: the metadata of a dataset at ``path`` (its ``data`` folder or the file) if
    Minari may read it without running code, else :class:`DatasetRefused` naming the file."""
    path = Path(path)
    if path.is_dir():
        path = path / METADATA
    meta = read_metadata(path)
    for key in ("observation_space", "action_space"):
        text = meta.get(key)
        if not isinstance(text, str):
            raise DatasetRefused(
                f"{path}: {key} is missing; Minari would build the env its env_spec names to "
                "learn it, so this dataset is refused"
            )
        try:
            space = json.loads(text)
        except (ValueError, RecursionError):
            space = None
        _space(f"{path}: {key}", space)
    for key in ("env_spec", "eval_env_spec"):
        if meta.get(key) is not None:
            check_env_spec(f"{path}: {key}", meta[key])
    for key, cap in (("total_episodes", "dataset_episodes"), ("total_steps", "dataset_steps")):
        if key in meta:
            try:
                check_size(f"{path}: {key}", meta[key], cap, low=0)
            except (TypeError, ValueError) as e:
                raise DatasetRefused(str(e)) from None
    check_arrays(path.parent)
    return meta


DATA_FILE = "main_data.hdf5"
MAX_ROW_WIDTH = 1_024
"""The most numbers per step in a dataset array (ours hold tens)."""


MAX_OBJECTS = 100_000
"""The most groups and arrays the gate walks in a dataset's HDF5 file (ours hold a few dozen)."""


def check_arrays(folder: Path) -> None:
    """:class:`DatasetRefused` naming the file (and array) unless the dataset's HDF5 file is a
    regular file whose arrays all live in it and fit the caps, read from its headers before
    Minari allocates anything:

    - no external link (an array of another file), no virtual dataset (one mapped onto other
      files: a FIFO among them blocks the read), no external storage (raw bytes of another file);
    - no array of more rows than ``dataset_steps`` or rows wider than :data:`MAX_ROW_WIDTH`;
    - the bytes all arrays declare, summed, within ``dataset_bytes`` (a chunked array that was
      never written takes no room in the file but all of it in memory when read).
    """
    data = folder / DATA_FILE
    try:
        check_input(data, "dataset file")
    except FileNotFoundError:
        return
    except OSError as e:  # NotAFile (a FIFO, a device, a folder) or unreadable
        raise DatasetRefused(str(e) if isinstance(e, NotAFile) else f"{data}: {e}") from None
    try:
        import h5py
    except ImportError:  # Minari without HDF5 cannot read it either
        return
    try:
        with h5py.File(data, "r") as f:
            problem = _walk(h5py, f)
    except OSError as e:
        raise DatasetRefused(f"{data}: not a readable HDF5 file ({e})") from None
    if problem is not None:
        raise DatasetRefused(f"{data}: {problem}")


def _walk(h5py: Any, root: Any) -> str | None:
    """What in ``root``'s tree the gate refuses (:func:`check_arrays`), or None."""
    rows, width = CAPS["dataset_steps"] + 1, MAX_ROW_WIDTH  # observations: steps + 1 rows
    total, seen = 0, 0
    stack = [("", root)]
    while stack:
        where, group = stack.pop()
        for name in group:
            seen += 1
            if seen > MAX_OBJECTS:
                return f"more than {MAX_OBJECTS:,} groups and arrays"
            path = f"{where}/{name}" if where else name
            link = group.get(name, getlink=True)
            if isinstance(link, h5py.ExternalLink):
                return f"{path} is an external link (to {link.filename}): refused"
            if not isinstance(link, h5py.HardLink):
                continue  # a soft link names an object of this file, checked where it lives
            obj = group[name]
            if isinstance(obj, h5py.Group):
                if path.count("/") >= 32:
                    return f"{path}: groups nested deeper than 32 levels"
                stack.append((path, obj))
                continue
            if not isinstance(obj, h5py.Dataset):
                continue
            if obj.is_virtual:
                return f"{path} is a virtual dataset (mapped onto other files): refused"
            if obj.external:
                return f"array {path} is stored in another file (external storage): refused"
            shape = tuple(obj.shape or ())
            if lifted_now():
                continue
            if len(shape) and (shape[0] > rows or math.prod(shape[1:]) > width):
                return (
                    f"array {path} {shape} is larger than the cap ({rows - 1:,} rows of at most "
                    f"{width} numbers; strol_gym.limits.lift() lifts it)"
                )
            total += math.prod(shape) * obj.dtype.itemsize
            if total > CAPS["dataset_bytes"]:
                return (
                    f"its arrays declare more than {CAPS['dataset_bytes']:,} bytes in all (the "
                    "cap dataset_bytes; strol_gym.limits.lift() lifts it)"
                )
    return None


__all__ = [
    "DatasetRefused",
    "check_env_spec",
    "check_metadata",
    "dataset_path",
    "datasets_root",
    "read_metadata",
    "wrappers",
]
