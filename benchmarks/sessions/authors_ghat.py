"""The authors' study ĝ, read from a local checkout of their repository, never shipped.

Their ``user_study/g_data`` holds two torch state dicts: ``model_t1`` (Task 1) and ``model_t2``
(Tasks 2 and 3). The network is a fact of their ``user_study/model.py``: an MLP on
(x, u) concatenated, layers state → 256 → 256 → 128 → 64 → d with ReLU between and Tanh at the
output (hidden size 256, their default), x and u the logged pose (Task 1: its position only).
A file is read with ``torch.load(weights_only=True)`` alone, which refuses anything but tensors
and plain containers without running it; its shapes are checked against that architecture; the
forward pass here is plain numpy. Nothing of a file is written anywhere: logs name the file and
its SHA-256.

In the study their update was θ ← θ + g(x, 3Δ) + λ·ĝ(x, 3Δ) per logged pair (their ``limit_g``
does nothing there: their g has shape (1, d), and it acts on 1-D g only). The released code sets
λ = 0.25 for Task 1 and 1.0 for Tasks 2–3; the logged sessions are explained by λ = 0.25 on
every Task (docs/fidelity.md gives the measurement), so :data:`PAPER_LAMBDA` is that.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import itertools
import warnings
from pathlib import Path

import numpy as np

FILES = {1: "model_t1", 2: "model_t2", 3: "model_t2"}
"""Which file holds Study Task J's ĝ."""
STATE = {1: 3, 2: 6, 3: 6}
"""The logged pose's entries ĝ sees per Task (Task 1: the position)."""
FEATURES = {1: 3, 2: 4, 3: 4}
HIDDEN = (256, 256, 128, 64)
"""Their hidden layers (``hidden_size`` 256, then 256, 256/2, 256/4)."""
PAPER_LAMBDA = 0.25
MAX_BYTES = 16 * 2**20
"""A ĝ file larger than this is refused before it is read (theirs are ~0.44 MB)."""
FLAG = "--authors-ghat"


def layer_shapes(number: int) -> list[tuple[tuple[int, int], tuple[int]]]:
    """(weight, bias) shapes of Study Task ``number``'s ĝ, input to output."""
    sizes = (2 * STATE[number], *HIDDEN, FEATURES[number])
    return [((o, i), (o,)) for i, o in itertools.pairwise(sizes)]


def state_keys(number: int) -> list[str]:
    """Their state dict's keys: ``learner.{0,2,4,6,8}.{weight,bias}`` (ReLUs between)."""
    return [f"learner.{2 * k}.{p}" for k in range(len(HIDDEN) + 1) for p in ("weight", "bias")]


@dataclasses.dataclass(frozen=True)
class AuthorsGhat:
    """One of the authors' ĝ networks as numpy arrays (read at run time, never written)."""

    number: int
    path: Path
    sha256: str
    layers: tuple[tuple[np.ndarray, np.ndarray], ...]

    def __call__(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """ĝ(x, u) for batches (B, s) -> (B, d): ReLU MLP, Tanh output."""
        h = np.concatenate([np.asarray(x, np.float64), np.asarray(u, np.float64)], axis=-1)
        last = len(self.layers) - 1
        for k, (w, b) in enumerate(self.layers):
            h = h @ w.T + b
            h = np.tanh(h) if k == last else np.maximum(h, 0.0)
        return h

    def describe(self) -> dict[str, object]:
        """What a log says of it: the file's name and SHA-256, λ (no weight)."""
        return {"file": self.path.name, "sha256": self.sha256, "lambda": PAPER_LAMBDA}


def ghat_dir(gdir: str | Path) -> Path:
    """``--authors-ghat GDIR`` checked: a folder holding ``model_t1`` and ``model_t2``."""
    path = Path(gdir)
    if not path.is_dir():
        raise ValueError(
            f"{FLAG} {gdir}: not a folder (want a checkout's user_study/g_data, holding "
            f"{' and '.join(sorted(set(FILES.values())))})"
        )
    for name in sorted(set(FILES.values())):
        if not (path / name).exists():
            raise ValueError(
                f"{FLAG} {gdir}: no {name} in it (want a checkout's user_study/g_data)"
            )
    return path


def _read_state(path: Path) -> tuple[dict[str, object], str]:
    """The file's bytes (a regular file, size capped) through ``torch.load(weights_only=True)``
    only, and their SHA-256; ValueError naming the file otherwise."""
    import torch

    from strol_gym.files import read_regular

    data = read_regular(path, MAX_BYTES, what=f"{FLAG}:")
    try:
        with warnings.catch_warnings():  # its note on a file's pickle protocol is no error
            warnings.simplefilter("ignore", UserWarning)
            state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as e:  # an unpickler refusal, a damaged zip: all say "not plain tensors"
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ValueError(
            f"{FLAG}: {path}: refused, not a plain state dict of tensors "
            f"(torch.load(weights_only=True): {first[:200]})"
        ) from None
    if not isinstance(state, dict):
        raise ValueError(f"{FLAG}: {path}: want a state dict, got {type(state).__name__}")
    return state, hashlib.sha256(data).hexdigest()


def check_layers(state: dict[str, object], number: int, where: str) -> list[np.ndarray]:
    """The state dict's arrays in layer order, checked against the architecture."""
    import torch

    keys = state_keys(number)
    if sorted(state) != sorted(keys):
        raise ValueError(
            f"{where}: keys {sorted(state)[:12]} are not the authors' MLP's {keys} (Task {number})"
        )
    shapes = [s for pair in layer_shapes(number) for s in pair]
    out = []
    for key, shape in zip(keys, shapes, strict=True):
        t = state[key]
        if not isinstance(t, torch.Tensor) or tuple(t.shape) != shape:
            have = tuple(t.shape) if isinstance(t, torch.Tensor) else type(t).__name__
            raise ValueError(f"{where}: {key} has shape {have}, the architecture wants {shape}")
        arr = t.detach().to(torch.float64).numpy().copy()
        if not np.isfinite(arr).all():
            raise ValueError(f"{where}: {key} holds non-finite numbers")
        out.append(arr)
    return out


@functools.lru_cache(maxsize=8)
def _load(path: Path, number: int) -> AuthorsGhat:
    state, sha = _read_state(path)
    arrays = check_layers(state, number, f"{FLAG}: {path}")
    pairs = tuple((arrays[k], arrays[k + 1]) for k in range(0, len(arrays), 2))
    return AuthorsGhat(number, path, sha, pairs)


def load_authors_ghat(gdir: str | Path, number: int) -> AuthorsGhat:
    """Study Task ``number``'s ĝ from GDIR (a checkout's ``user_study/g_data``)."""
    if number not in FILES:
        raise ValueError(f"Study Task number must be 1, 2 or 3, got {number!r}")
    path = ghat_dir(gdir) / FILES[number]
    return _load(path.resolve(), number)


__all__ = [
    "FILES",
    "PAPER_LAMBDA",
    "AuthorsGhat",
    "check_layers",
    "ghat_dir",
    "layer_shapes",
    "load_authors_ghat",
    "state_keys",
]
