"""StROL and e2e: learning rules that use a trained correction term ĝ (paper, Section IV-B).

StROL: G = g + λ·ĝ (λ = 1 in the paper; λ = 0 is exactly Gradient). e2e: G = ĝ, the same
network trained without the designer's g in the update, still bounded by ‖g‖; e2e-scratch:
G = ĝ with ĝ unbounded, the paper's "completely from scratch". strol-unrolled: G = g + ĝ
with ĝ also conditioned on θ̂ and trained through K unrolled corrections. In all but
e2e-scratch, ĝ is bounded by ‖ĝ‖ ≤ ‖g‖ (see ``strol_gym.learners.network``). By default the
learner loads the ĝ shipped for the task (``strol_gym/pretrained``), looked up by ``task.task_id``.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch

from strol_gym import checks
from strol_gym.learners.checkpoint import (
    MAX_WEIGHT,
    check_finite_weights,
    find_pretrained,
    input_dim,
    load_checkpoint,
    model_input,
    register_kind,
    train_hint,
)
from strol_gym.learners.network import CorrectionNet
from strol_gym.learners.protocol import LinearRuleLearner, check_state
from strol_gym.tasks.base import Task


@contextmanager
def _one_thread() -> Iterator[None]:
    """Run ĝ on one thread: for a small MLP on a few rows, torch's intra-op threads cost
    more than they save (measured ~0.5 ms vs ~7 ms per update on a busy 2-core machine)."""
    prev = torch.get_num_threads()
    if prev == 1:
        yield
        return
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(prev)


class CorrectionLearner(LinearRuleLearner):
    """Shared machinery: holds ĝ and evaluates it on numpy batches (float64 bound)."""

    kind: str = ""
    """The ĝ kind: which checkpoints fit (a subclass's kind registers itself)."""
    sees_theta_hat: bool = False
    """Whether ĝ also sees the current estimate θ̂ (appended to the task's input)."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.kind:
            register_kind(cls.kind, sees_theta_hat=cls.sees_theta_hat)

    def __init__(
        self,
        task: Task,
        checkpoint: str | Path | None = None,
        model: CorrectionNet | None = None,
    ) -> None:
        super().__init__(task)
        self.checkpoint: str | None = None
        self.checkpoint_meta: dict[str, Any] | None = None
        """Where ĝ came from (None: a model passed in) and its sidecar."""
        if model is not None and checkpoint is not None:
            raise ValueError("pass either checkpoint or model, not both")
        if checkpoint is not None and not isinstance(checkpoint, str | os.PathLike):
            raise checks.ArgumentTypeError(
                f"checkpoint must be a path to a .safetensors (or .pt) file, got {checkpoint!r}"
            )
        if model is None:
            # The shipped ĝ of the Task's setting (``Task.ghat_task``: itself, or a version's
            # predecessor); a checkpoint given explicitly must fit the Task itself.
            source = task if checkpoint is not None else task.ghat_task
            path = (
                Path(checkpoint) if checkpoint is not None else find_pretrained(source, self.kind)
            )
            try:
                model, meta = load_checkpoint(path, source, kind=self.kind)
            except ValueError as e:
                if checkpoint is not None:
                    raise
                # the shipped ĝ of the env's setting, but this Task differs (a variant)
                raise ValueError(f"{e}; {train_hint(task, self.kind)}") from None
            self.checkpoint = str(path)
            self.checkpoint_meta = meta
        else:
            if not isinstance(model, CorrectionNet):
                raise ValueError(f"model must be a CorrectionNet, got {type(model).__name__}")
            want = input_dim(task, self.kind)
            if model.in_dim != want or model.out_dim != task.dim:
                raise ValueError(
                    f"model maps {model.in_dim} -> {model.out_dim}, a {self.kind} ĝ for task "
                    f"{task.task_id} needs {want} -> {task.dim}"
                )
            self.checkpoint = None
            self.checkpoint_meta = None
        self.model = model.eval()

    def correction(
        self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray, theta: np.ndarray | None = None
    ) -> np.ndarray:
        """ĝ for a batch, (B, s), (B, a), (B, a) -> (B, d), with ‖ĝ‖ < ‖g‖ row by row.
        ``theta`` (B, d), the current estimate, is needed by kinds that condition on it."""
        return self._correction_and_g(x, u_h, u_r, theta)[0]

    def _correction_and_g(self, x, u_h, u_r, theta=None) -> tuple[np.ndarray, np.ndarray]:
        g = self.task.g(x, u_h, u_r)
        theta = self.theta if theta is None else theta
        z = torch.as_tensor(
            model_input(self.task, self.kind, x, u_h, u_r, theta), dtype=torch.float32
        )
        with torch.no_grad(), _one_thread():
            g_hat = self.model(z, torch.as_tensor(g, dtype=torch.float64))
        return g_hat.numpy(), g

    def state_dict(self) -> dict[str, Any]:
        state = super().state_dict()
        state["model"] = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
        state["arch"] = self.model.arch()
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore θ̂ and ĝ, or raise and leave both untouched (ĝ is loaded into a copy first)."""
        check_state(state, self.name)
        if state.get("arch") != self.model.arch():
            raise ValueError(
                f"state network {state.get('arch')} differs from this learner's {self.model.arch()}"
            )
        model = copy.deepcopy(self.model)
        weights = state.get("model")
        if not isinstance(weights, dict):
            raise ValueError("state['model'] must be the network's state_dict")
        current = self.model.state_dict()
        for key, value in weights.items():
            want = current.get(key)
            if not torch.is_tensor(value) or want is None or value.dtype != want.dtype:
                raise ValueError(
                    f"state['model'][{key!r}] must be a {getattr(want, 'dtype', 'known')} tensor "
                    f"(the network's own), got {getattr(value, 'dtype', type(value).__name__)}"
                )
            if value.is_floating_point() and value.abs().max() > MAX_WEIGHT:
                raise ValueError(
                    f"state['model'][{key!r}] holds a weight beyond ±{MAX_WEIGHT:g} (trained "
                    "weights are far smaller; such a network overflows at the first update)"
                )
        try:
            model.load_state_dict(weights)
        except RuntimeError as e:
            raise ValueError(f"state['model'] does not fit this learner's network ({e})") from None
        check_finite_weights(weights, "state['model']")
        super().load_state_dict(state)  # checks θ̂ before it assigns it
        self.model = model.eval()


MAX_LAM = 1000.0
"""Largest λ: 100x the λ sweep's largest; beyond it λ·ĝ swamps g and θ̂ runs off."""


class StROLLearner(CorrectionLearner):
    """StROL: θ̂ ← θ̂ + α·(g + λ·ĝ). ``lam`` = λ ≥ 0; default: the Task's ``strol_lambda`` if
    it has one (the user study's 0.25 for Task 1, 1.0 for Tasks 2-3), else 1 (as trained)."""

    name = "strol"
    kind = "strol"

    def __init__(
        self,
        task: Task,
        lam: float | None = None,
        checkpoint: str | Path | None = None,
        model: CorrectionNet | None = None,
    ) -> None:
        raw = getattr(task, "strol_lambda", 1.0) if lam is None else lam
        self.lam = float(checks.number("lam", raw, low=0, high=MAX_LAM, text=True))
        super().__init__(task, checkpoint=checkpoint, model=model)

    def config(self) -> dict[str, Any]:
        return {"lam": self.lam}

    def direction(self, x, u_h, u_r, theta) -> np.ndarray:
        g_hat, g = self._correction_and_g(x, u_h, u_r, theta)
        return g + self.lam * g_hat


class E2ELearner(CorrectionLearner):
    """e2e: θ̂ ← θ̂ + α·ĝ, the ablation that learns the rule from scratch (same network)."""

    name = "e2e"
    kind = "e2e"

    def direction(self, x, u_h, u_r, theta) -> np.ndarray:
        return self.correction(x, u_h, u_r)


class E2EScratchLearner(E2ELearner):
    """e2e as the paper defines it: θ̂ ← θ̂ + α·ĝ with ĝ *unbounded* (``bound="none"``), the
    learning rule "trained completely from scratch" (nothing of g enters ĝ). ``e2e`` is the
    same rule with ‖ĝ‖ ≤ ‖g‖ (docs/fidelity.md says why both exist)."""

    name = "e2e-scratch"
    kind = "e2e-scratch"


class UnrolledStROLLearner(StROLLearner):
    """strol-unrolled: θ̂ ← θ̂ + α·(g + λ·ĝ(x, u_H, θ̂)), λ = ``lam`` (default 1, as trained).

    The same rule as StROL, but ĝ also sees the current estimate θ̂, and it was trained through
    K unrolled corrections (``--kind strol-unrolled --unroll K``): the loss is the error after K
    updates, with the eq. M6 human re-choosing its correction from the current θ̂ at each step
    (docs/training.md). Assumes the human resembles that training human: eq. M6 with the
    training noise, θ* from the designer's bimodal prior. ‖ĝ‖ ≤ ‖g‖ holds as for StROL.
    """

    name = "strol-unrolled"
    kind = "strol-unrolled"
    sees_theta_hat = True
