"""ĝ, the learned correction term: an MLP whose output is bounded by the size of g.

The paper bounds ĝ with a tanh output so that ‖ĝ‖ ≤ ‖g‖: the correction may turn and stretch
the designer's update, never overpower it. We use a *radial* tanh squash by default,

    s(o) = o · tanh(‖o‖) / ‖o‖,   ĝ = c · ‖g‖ · s(o),   c = 1 − 1e-6,

so ‖s‖ < 1 in every direction (the per-component ``"box"`` variant, tanh(o)/√d, only reaches
‖g‖ along the diagonals). The factor c keeps ‖ĝ‖ < ‖g‖ even after float rounding. The bound is
part of the forward pass, so it holds in training and in use alike.

``"none"`` is the unbounded network, ĝ = o: nothing of g enters it. It is the paper's e2e,
whose rule is "trained completely from scratch" (kind ``e2e-scratch``); StROL keeps its bound.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import nn

BOUNDS = ("radial", "box", "none")
SHRINK = 1.0 - 1e-6
DEFAULT_HIDDEN = (256, 256, 128, 64)


def bound_correction(raw: torch.Tensor, g: torch.Tensor, mode: str = "radial") -> torch.Tensor:
    """Map raw network outputs (..., d) to ĝ with ‖ĝ‖ < ‖g‖ (for g ≠ 0; ĝ = 0 where g = 0);
    ``"none"`` returns them unchanged (in g's dtype).

    The margin is 1e-6 relative: it holds as long as ‖g‖² is a normal float of g's dtype
    (‖g‖ above about 1e-19 in float32, 1e-154 in float64); below that the norms themselves
    are computed from subnormal squares and carry more rounding than the margin.
    """
    if mode == "none":
        return raw.to(g.dtype)
    if mode == "radial":
        r = torch.sqrt((raw * raw).sum(dim=-1, keepdim=True) + 1e-12)
        s = raw * (torch.tanh(r) / r)
    elif mode == "box":
        s = torch.tanh(raw) / math.sqrt(raw.shape[-1])
    else:
        raise ValueError(f"bound must be one of {BOUNDS}, got {mode!r}")
    return (SHRINK * torch.linalg.vector_norm(g, dim=-1, keepdim=True)) * s


class CorrectionNet(nn.Module):
    """ĝ(z; g): ReLU MLP over the task's network input z, squashed and scaled by ‖g‖.

    The input is standardised with fixed buffers (``in_mean``, ``in_std``) that training sets
    from its data, so one architecture serves tasks whose inputs have different units.
    """

    def __init__(
        self,
        in_dim: int,
        out_dim: int,
        hidden: Sequence[int] = DEFAULT_HIDDEN,
        bound: str = "radial",
    ) -> None:
        super().__init__()
        if in_dim < 1 or out_dim < 1:
            raise ValueError(f"in_dim and out_dim must be >= 1, got {in_dim}, {out_dim}")
        if (
            not isinstance(hidden, Sequence)
            or isinstance(hidden, str | bytes)
            or not hidden
            or any(isinstance(h, bool) or not hasattr(h, "__index__") or h < 1 for h in hidden)
        ):
            raise ValueError(
                f"hidden must be a non-empty list of positive integer widths, got {hidden!r}"
            )
        if bound not in BOUNDS:
            raise ValueError(f"bound must be one of {BOUNDS}, got {bound!r}")
        self.in_dim, self.out_dim = int(in_dim), int(out_dim)
        self.hidden = tuple(int(h) for h in hidden)
        self.bound = bound
        layers: list[nn.Module] = []
        width = self.in_dim
        for h in self.hidden:
            layers += [nn.Linear(width, h), nn.ReLU()]
            width = h
        layers.append(nn.Linear(width, self.out_dim))
        self.mlp = nn.Sequential(*layers)
        self.register_buffer("in_mean", torch.zeros(self.in_dim))
        self.register_buffer("in_std", torch.ones(self.in_dim))

    def arch(self) -> dict:
        """The constructor arguments (JSON-ready), stored in checkpoints."""
        return {
            "in_dim": self.in_dim,
            "out_dim": self.out_dim,
            "hidden": list(self.hidden),
            "bound": self.bound,
        }

    in_mean: torch.Tensor
    in_std: torch.Tensor
    """The input's standardisation (buffers: saved with the weights, set by training)."""

    def raw(self, z: torch.Tensor) -> torch.Tensor:
        """The unbounded output o(z), (..., in_dim) -> (..., out_dim)."""
        return self.mlp((z - self.in_mean) / self.in_std)

    def forward(self, z: torch.Tensor, g: torch.Tensor) -> torch.Tensor:
        """ĝ(z) with ‖ĝ‖ < ‖g‖, computed in g's dtype."""
        return bound_correction(self.raw(z).to(g.dtype), g, self.bound)
