"""Checkpoints of ĝ: weights as a safetensors file (plain tensors behind a JSON header: reading
it runs no code and needs no unpickler) plus a JSON sidecar that says what they are for.

A torch state_dict in a ``.pt`` file still loads (with ``weights_only=True``, never a pickled
object) and can be written on request, so users' own checkpoints keep working; the shipped
weights and ``strol-bench train``'s default are safetensors. ``--convert`` turns a ``.pt`` into
a ``.safetensors`` with the same tensors, bit for bit, through the same writer training uses.

The sidecar (``<name>.json`` next to ``<name>.safetensors``) records the task (id, version,
feature names, dims, α, action bound), the network input width and architecture, the kind
("strol" | "e2e" | ...), the training config and seed, package versions, the SHA-256 of the weights
file, the final loss and the held-out Lyapunov check. Loading compares it with the Task and
raises ValueError naming every difference.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors.torch import load as load_safetensors
from safetensors.torch import save as save_safetensors

from strol_gym import checks
from strol_gym.files import (
    check_input,
    check_output,
    loads_json,
    open_regular,
    read_regular,
    replace_checked,
    temp_beside,
    write_text_atomic,
)
from strol_gym.learners.network import CorrectionNet
from strol_gym.provenance import package_versions
from strol_gym.tasks.base import Task

FORMAT_VERSION = 1
KINDS: dict[str, bool] = {}
"""The ĝ kinds, each with whether its ĝ also sees θ̂: a ``CorrectionLearner`` subclass
registers its ``kind`` when it is defined (``register_kind``); the built-in ones are here from
the start, so training and the sidecar checks know them before any learner is imported."""
THETA_KINDS: set[str] = set()
"""Kinds whose ĝ also sees the robot's current estimate θ̂ (appended to the task's input)."""


def register_kind(name: str, *, sees_theta_hat: bool = False) -> None:
    """Make ``name`` a ĝ kind (``--kind`` of training, a checkpoint's ``kind``). Registering a
    known kind again is a no-op if it agrees, else an error."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"kind must be a non-empty string, got {name!r}")
    if KINDS.get(name, sees_theta_hat) != sees_theta_hat:
        raise ValueError(f"kind {name!r} is registered with sees_theta_hat={KINDS[name]}")
    KINDS[name] = bool(sees_theta_hat)
    if sees_theta_hat:
        THETA_KINDS.add(name)


for _kind, _sees in (
    ("strol", False),
    ("e2e", False),
    ("strol-unrolled", True),
    ("e2e-scratch", False),
):
    register_kind(_kind, sees_theta_hat=_sees)
PRETRAINED_DIR = Path(__file__).resolve().parent.parent / "pretrained"
SAFETENSORS, TORCH_PT = ".safetensors", ".pt"
WEIGHTS_SUFFIXES = (SAFETENSORS, TORCH_PT)
"""The weights formats, the default (what ships, what training writes) first."""


def weights_sha256(path: str | Path) -> str:
    """SHA-256 of a weights file's bytes: the sidecar's ``weights_sha256``, so a sidecar only
    vouches for the exact file it was written for."""
    h = hashlib.sha256()
    _hash_file(h, Path(path))
    return h.hexdigest()


HASH_CHUNK = 1 << 20


def _hash_file(h: Any, path: Path, prefix_length: bool = False) -> None:
    """Feed ``path``'s bytes to ``h`` in 1 MiB chunks (a 1 GB file costs 1 MiB of memory),
    preceded by its length (8 bytes, little-endian) if ``prefix_length``."""
    with open_regular(path, "weights") as f:
        if prefix_length:
            h.update(os.fstat(f.fileno()).st_size.to_bytes(8, "little"))
        while chunk := f.read(HASH_CHUNK):
            h.update(chunk)


MAX_WEIGHT = 1e6
"""The largest |weight| a checkpoint or a learner's state may hold: trained networks hold
weights below 10; far larger ones (1e30) overflow float32 activations at the first update,
which would then seem to blame its inputs."""


def check_finite_weights(weights: dict[str, Any], where: str) -> None:
    """ValueError naming ``where`` and the tensor if any weight is not a float (an int64
    tensor), NaN or inf, or larger in size than :data:`MAX_WEIGHT`."""
    for key, value in weights.items():
        if not torch.is_tensor(value):
            continue
        if not value.is_floating_point():
            raise ValueError(f"{where}: weight {key!r} is {value.dtype}, not floating point")
        if not torch.isfinite(value).all():
            raise ValueError(f"{where}: weight {key!r} contains NaN or inf")
        if value.numel() and float(value.abs().max()) > MAX_WEIGHT:
            raise ValueError(f"{where}: weight {key!r} holds a value beyond ±{MAX_WEIGHT:g}")


def check_shapes(weights: Any, net: Any, where: str) -> None:
    """ValueError unless ``weights`` has exactly the tensors, of the shapes, that the sidecar's
    ``network`` (in_dim, out_dim, hidden, bound) needs.

    The expected shapes come from the network built on torch's "meta" device, which stores no
    data, so an edited sidecar (``hidden: [1000000000]``) costs nothing here, and the real
    network is built only once it is known to be as large as the weights file itself.
    """
    if not isinstance(weights, dict) or not all(torch.is_tensor(v) for v in weights.values()):
        raise ValueError(f"{where}: the weights file must hold a dict of tensors")
    if not isinstance(net, dict):
        raise ValueError(f"{where}: the sidecar's 'network' must be an object")
    try:
        with torch.device("meta"):
            ghost = CorrectionNet(net["in_dim"], net["out_dim"], net["hidden"], net["bound"])
    except (KeyError, TypeError, ValueError) as e:
        raise ValueError(f"{where}: the sidecar's network {net} is invalid ({e})") from None
    want = {k: tuple(v.shape) for k, v in ghost.state_dict().items()}
    have = {k: tuple(v.shape) for k, v in weights.items()}
    if want != have:
        diff = sorted(k for k in set(want) | set(have) if want.get(k) != have.get(k))
        detail = ", ".join(f"{k}: sidecar {want.get(k)}, weights {have.get(k)}" for k in diff[:3])
        raise ValueError(f"{where}: the sidecar's network does not match the weights ({detail})")


def checkpoint_sha256(path: str | Path) -> str:
    """SHA-256 over a checkpoint's weights file and its sidecar, each preceded by its length:
    what identifies a ĝ in a results folder, since the sidecar (network, bound) shapes the
    learner's behaviour as much as the weights do."""
    h = hashlib.sha256()
    for part in (Path(path), sidecar_path(path)):
        _hash_file(h, part, prefix_length=True)
    return h.hexdigest()


def check_weights_path(path: str | Path, name: str = "path") -> Path:
    """Where a checkpoint will be written: a ``.safetensors`` (or ``.pt``) file in a folder we
    can create and write.

    Training calls it first, so a bad ``--out`` fails at once rather than after the work.
    """
    path = Path(path)
    if path.suffix not in WEIGHTS_SUFFIXES:
        raise ValueError(
            f"{name} must be a file ending in .safetensors (or .pt for a torch state_dict), "
            f"got {path}"
        )
    if path.is_dir():
        raise ValueError(f"{name} {path} is a folder; give a file name ending in .safetensors")
    check_output(path, name)
    check_output(sidecar_path(path), f"{name}'s sidecar")
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise ValueError(f"{name} {path}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{name} {path}: cannot write in {folder} (permission denied)")
    probe_writable(folder, f"{name} {path}")
    return path


def probe_writable(folder: Path, what: str) -> None:
    """ValueError naming ``what`` unless a file can be created (and removed) in ``folder``.

    ``os.access`` says yes for root everywhere and for pseudo file systems such as /proc;
    creating a file is the one test that cannot be wrong.
    """
    import tempfile

    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".strol-probe-"):
            pass
    except OSError as e:
        raise ValueError(f"{what}: cannot write in {folder} ({e.strerror or e})") from None


def write_weights(dest: Path, weights: dict[str, torch.Tensor], suffix: str) -> None:
    """Write ``weights`` to ``dest`` in the format ``suffix`` names: safetensors (the same
    tensors always give the same bytes) or, for ``.pt``, a torch state_dict."""
    if suffix == TORCH_PT:
        torch.save(weights, dest)
    else:
        dest.write_bytes(save_safetensors(weights))


def read_weights(path: Path) -> dict[str, torch.Tensor]:
    """The tensors of a weights file, without an unpickler for safetensors; a ``.pt`` goes
    through ``torch.load(weights_only=True)``, which refuses anything but tensors and
    containers. ValueError naming the file if it cannot be read."""
    try:
        if path.suffix == TORCH_PT:
            return torch.load(check_input(path, "weights"), map_location="cpu", weights_only=True)
        # safetensors checks that its header fits the file and that every tensor's byte range
        # lies inside it, so a damaged or edited file cannot ask for more memory than it has.
        return load_safetensors(read_regular(path, what="weights"))
    except Exception as e:  # a damaged file fails in either reader in many ways
        raise ValueError(f"{path}: cannot read these weights ({e})") from None


def sidecar_path(path: str | Path) -> Path:
    """The JSON sidecar beside a weights file."""
    return Path(path).with_suffix(".json")


def input_dim(task: Task, kind: str | None) -> int:
    """The width of ĝ's input for ``kind``: the task's network input (+ d for θ̂ kinds)."""
    return int(task.network_input_dim) + (task.dim if kind in THETA_KINDS else 0)


def model_input(
    task: Task, kind: str, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    """What ĝ of ``kind`` sees: ``task.network_input(x, u_h, u_r)``, then θ̂ for θ̂ kinds."""
    z = task.network_input(x, u_h, u_r)
    if kind in THETA_KINDS:
        theta = np.broadcast_to(theta, (*z.shape[:-1], task.dim))
        z = np.concatenate([z, theta], axis=-1)
    return z


def task_signature(task: Task) -> dict[str, Any]:
    """What a checkpoint must agree on with the Task it is used for."""
    sig = dict(task.describe())
    sig["network_input_dim"] = int(task.network_input_dim)
    return sig


def save_checkpoint(
    path: str | Path,
    model: CorrectionNet,
    task: Task,
    kind: str,
    config: dict[str, Any] | None = None,
    extra: dict[str, Any] | None = None,
) -> Path:
    """Write ``path`` (weights) and its JSON sidecar. Returns the weights path."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {tuple(KINDS)}, got {kind!r}")
    path = Path(path)
    check_weights_path(path)
    if model.in_dim != input_dim(task, kind) or model.out_dim != task.dim:
        raise ValueError(
            f"model maps {model.in_dim} -> {model.out_dim}, a {kind} ĝ for task {task.task_id} "
            f"needs {input_dim(task, kind)} -> {task.dim}"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    weights = {k: v.detach().cpu().contiguous().clone() for k, v in model.state_dict().items()}
    check_finite_weights(weights, "model")
    # Both files go to temporaries first and are renamed, sidecar first: a failure (a full
    # disk) leaves no partial weights file, and never weights without their sidecar.
    tmp_pt = temp_beside(path, lambda tmp: write_weights(tmp, weights, path.suffix))
    meta = {
        "format_version": FORMAT_VERSION,
        "kind": kind,
        "weights_sha256": weights_sha256(tmp_pt),
        "task": task_signature(task),
        "network": model.arch(),
        "training": config or {},
        "versions": package_versions(),
        **(extra or {}),
    }
    _commit(path, tmp_pt, meta)
    return path


def _commit(path: Path, tmp_weights: Path, meta: dict[str, Any]) -> None:
    """Write ``meta`` as ``path``'s sidecar and move the written ``tmp_weights`` to ``path``:
    sidecar first, so a failure never leaves weights without their sidecar. The temporary is
    gone afterwards either way."""
    text = json.dumps(meta, indent=2, sort_keys=True) + "\n"
    side = sidecar_path(path)
    try:
        tmp_json = temp_beside(side, lambda tmp: tmp.write_text(text))
        try:
            check_output(path)  # both checked before either is renamed
            replace_checked(tmp_json, side)
        finally:
            tmp_json.unlink(missing_ok=True)
        replace_checked(tmp_weights, path)
    finally:
        tmp_weights.unlink(missing_ok=True)


def read_sidecar(path: str | Path) -> dict[str, Any]:
    side = sidecar_path(path)
    if not side.is_file():
        raise FileNotFoundError(f"checkpoint sidecar {side} is missing (needed beside {path})")
    meta = loads_json(read_regular(side, what="checkpoint sidecar"), f"checkpoint sidecar {side}")
    if not isinstance(meta, dict):
        raise ValueError(f"checkpoint sidecar {side} must hold a JSON object")
    for key, kind in (("task", dict), ("network", dict), ("kind", str)):
        if key in meta and not isinstance(meta[key], kind):
            word = "an object" if kind is dict else "a string"
            raise ValueError(
                f"checkpoint sidecar {side}: {key!r} must be {word}, got {meta[key]!r:.80}"
            )
    return meta


def check_weights_hash(path: str | Path, meta: dict[str, Any]) -> None:
    """ValueError naming the file unless the sidecar's ``weights_sha256`` matches its bytes."""
    want = meta.get("weights_sha256")
    rehash = f"`python -m strol_gym.learners.checkpoint --rehash {path}`"
    if not isinstance(want, str):
        raise ValueError(
            f"{path}: its sidecar {sidecar_path(path)} has no weights_sha256, so nothing says "
            f"these weights are the ones it describes; if they are, record their hash with {rehash}"
        )
    if weights_sha256(path) != want:
        raise ValueError(
            f"{path}: the weights do not match their sidecar {sidecar_path(path)} (SHA-256 "
            f"differs): they are another checkpoint's weights (another kind or task) or were "
            f"changed after saving"
        )


def rehash_sidecar(path: str | Path) -> str:
    """Record the SHA-256 of ``path`` in its sidecar (nothing else changes); returns it.

    For sidecars written before the hash existed: run it only on weights you trust.
    """
    side = sidecar_path(path)
    meta = read_sidecar(path)
    meta["weights_sha256"] = weights_sha256(path)
    write_text_atomic(side, json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return meta["weights_sha256"]


def check_sidecar(meta: dict[str, Any], task: Task, kind: str | None = None) -> None:
    """Raise ValueError listing every way ``meta`` disagrees with ``task`` (and ``kind``)."""
    problems = []
    if meta.get("format_version") != FORMAT_VERSION:
        problems.append(f"format_version {meta.get('format_version')} != {FORMAT_VERSION}")
    if kind is not None and meta.get("kind") != kind:
        problems.append(f"kind: checkpoint has {meta.get('kind')!r}, expected {kind!r}")
    have, want = meta.get("task", {}), task_signature(task)
    if not isinstance(have, dict) or not isinstance(meta.get("network", {}), dict):
        raise ValueError("checkpoint sidecar: 'task' and 'network' must be JSON objects")
    for key in sorted(set(have) | set(want)):
        a, b = have.get(key), want.get(key)
        if a == b:
            continue
        if isinstance(a, dict) and isinstance(b, dict):  # name only the fields that differ
            for sub in sorted(set(a) | set(b)):
                if a.get(sub) != b.get(sub):
                    problems.append(
                        f"{key}.{sub}: checkpoint has {a.get(sub)!r}, task has {b.get(sub)!r}"
                    )
        else:
            problems.append(f"{key}: checkpoint has {a!r}, task has {b!r}")
    net = meta.get("network", {})
    if net.get("out_dim") != task.dim:
        problems.append(f"network out_dim {net.get('out_dim')} != task dim {task.dim}")
    want_in = input_dim(task, meta.get("kind") if kind is None else kind)
    if meta.get("kind") in KINDS and net.get("in_dim") != want_in:
        problems.append(f"network in_dim {net.get('in_dim')} != {want_in}")
    if problems:
        raise ValueError("checkpoint does not match the task: " + "; ".join(problems))


def load_checkpoint(
    path: str | Path, task: Task, kind: str | None = None
) -> tuple[CorrectionNet, dict[str, Any]]:
    """Load a ĝ checked against ``task`` (and ``kind`` if given). Returns (model, sidecar)."""
    if not isinstance(path, str | os.PathLike):
        raise checks.ArgumentTypeError(
            f"checkpoint must be a path to a .safetensors (or .pt) file, got {path!r}"
        )
    path = Path(path)
    if path.suffix not in WEIGHTS_SUFFIXES:
        raise ValueError(
            f"checkpoint must be a .safetensors (or .pt) file, got {path} (the suffix says "
            "how the weights are read)"
        )
    if not path.is_file():
        raise FileNotFoundError(f"no checkpoint at {path}")
    meta = read_sidecar(path)
    try:
        check_sidecar(meta, task, kind)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None
    check_weights_hash(path, meta)
    net = meta["network"]
    weights = read_weights(path)
    check_shapes(weights, net, str(path))  # before the network is built: nothing large
    model = CorrectionNet(net["in_dim"], net["out_dim"], net["hidden"], net["bound"])
    try:
        model.load_state_dict(weights)
    except Exception as e:
        raise ValueError(
            f"{path}: cannot load these weights into its sidecar's network ({e})"
        ) from None
    check_finite_weights(weights, str(path))
    model.eval()
    return model, meta


def find_pretrained(task: Task, kind: str, directory: str | Path = PRETRAINED_DIR) -> Path:
    """The shipped checkpoint whose sidecar names ``task.task_id`` and ``kind``.

    Files are looked up by their sidecars, not by name; the convention for names is
    ``<task.weights_stem or its registry name>_<kind>.safetensors`` (``robot_strol.safetensors``,
    ``study1-v2_strol.safetensors``). A sidecar with
    weights in both formats beside it counts once, the safetensors file.
    """
    directory = Path(directory)
    found = []
    for side in sorted(directory.glob("*.json")):
        try:
            meta = loads_json(read_regular(side, what="checkpoint sidecar"), str(side))
        except (OSError, ValueError):
            continue
        if not isinstance(meta, dict) or not isinstance(meta.get("task"), dict):
            continue
        if meta.get("kind") == kind and meta.get("task", {}).get("task_id") == task.task_id:
            weights = [side.with_suffix(s) for s in WEIGHTS_SUFFIXES]
            found += [w for w in weights if w.is_file()][:1]
    if not found:
        raise FileNotFoundError(
            f"no pretrained {kind} ĝ for {task.task_id} in {directory}; {train_hint(task, kind)}"
        )
    if len(found) > 1:
        raise ValueError(f"several pretrained {kind} ĝ for {task.task_id}: {found}")
    return found[0]


def train_hint(task: Task, kind: str) -> str:
    """How to train a ``kind`` ĝ for ``task`` and use it, as commands that work when pasted
    (the Task's registry name, and the ``--plugin`` that defines it)."""
    import shlex

    from strol_gym.registry import plugin_argument
    from strol_gym.tasks import task_name

    try:
        name = task_name(task)
    except ValueError:  # a Task defined where no other process can import it
        name = task.task_id
    stem = task.weights_stem or (name if ":" not in name else type(task).__name__)
    out = f"{stem}_{kind}{SAFETENSORS}"
    plugin = plugin_argument(type(task))
    train = ["strol-bench", "train", *(["--plugin", plugin] if plugin else [])]
    train += ["--task", name, "--kind", kind, "--out", out]
    kwargs = json.dumps({kind: {"checkpoint": out}})
    return (
        f"train one with `{shlex.join(train)}` and pass it to the learner: "
        f"`--learner-kwargs {shlex.quote(kwargs)}` on the strol-bench command line, "
        f"checkpoint={out!r} in Python"
    )


def convert_to_safetensors(path: str | Path) -> Path:
    """Write ``<name>.safetensors`` and its sidecar ``<name>.json`` from the checkpoint
    ``<name>.pt``: the same tensors bit for bit (checked by reading the new file back), through
    the writer ``save_checkpoint`` uses, so converted and newly trained weights are alike. The
    sidecar changes only in ``weights_sha256``. The ``.pt`` is kept; delete it yourself.

    The ``.pt`` must match its sidecar's hash first: only weights the sidecar vouches for are
    converted.
    """
    path = Path(path)
    if path.suffix != TORCH_PT:
        raise ValueError(f"--convert takes a .pt checkpoint, got {path}")
    meta = read_sidecar(path)
    check_weights_hash(path, meta)
    weights = read_weights(path)
    check_shapes(weights, meta.get("network"), str(path))
    check_finite_weights(weights, str(path))
    out = path.with_suffix(SAFETENSORS)
    tmp = temp_beside(out, lambda t: write_weights(t, weights, SAFETENSORS))
    try:
        back = read_weights(tmp)  # not .pt: read as safetensors
        same = back.keys() == weights.keys() and all(
            back[k].dtype == v.dtype
            and back[k].shape == v.shape
            and back[k].numpy().tobytes() == v.contiguous().numpy().tobytes()
            for k, v in weights.items()
        )
        if not same:
            raise ValueError(f"{path}: the safetensors copy does not hold the same tensors")
        meta["weights_sha256"] = weights_sha256(tmp)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _commit(out, tmp, meta)
    return out


def main(argv: list[str] | None = None) -> None:
    """``python -m strol_gym.learners.checkpoint --rehash FILE ...`` records weights hashes;
    ``--convert FILE.pt ...`` writes safetensors copies of torch checkpoints."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m strol_gym.learners.checkpoint",
        description="Record the SHA-256 of trusted weights files in their JSON sidecars, or "
        "convert .pt checkpoints to .safetensors (same tensors, sidecar hash updated).",
    )
    todo = parser.add_mutually_exclusive_group(required=True)
    todo.add_argument("--rehash", nargs="+", metavar="FILE")
    todo.add_argument("--convert", nargs="+", metavar="FILE.pt")
    args = parser.parse_args(argv)
    for path in args.rehash or args.convert:
        try:
            if args.rehash:
                print(f"{path}: weights_sha256 {rehash_sidecar(path)}")
            else:
                print(f"{path} -> {convert_to_safetensors(path)}")
        except (OSError, ValueError) as e:
            parser.exit(2, f"error: {e}\n")


if __name__ == "__main__":
    main()
