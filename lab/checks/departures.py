"""Task variants that measure two departures from the paper (docs/fidelity.md).

- ``robot_alpha1``: the Robot Task with the authors' α = 1 instead of our α = 2.
- ``RobotTaskXR``: the Robot Task whose ĝ sees the state the rule's g is evaluated at,
  x_R = f(x, 0, u_R), instead of x (paper eq. G writes ĝ(x, u_H, u_R, θ)); its own task id, so
  its weights never load for the shipped Task.

Each is used (from the repository root) by
``PYTHONPATH=. strol-bench train --task lab.checks.departures:NAME``
and ``strol-bench run --task ...`` with the trained checkpoints (commands in docs/fidelity.md).
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from strol_gym.tasks.robot import RobotTask


def robot_alpha1() -> RobotTask:
    """The Robot Task at the authors' learning rate, α = 1."""
    return RobotTask(alpha=1.0)


@dataclasses.dataclass(frozen=True, eq=False)
class RobotTaskXR(RobotTask):
    """The Robot Task with ĝ's input (x_R, u_H/a_max), x_R = f(x, 0, u_R)."""

    task_id: ClassVar[str] = "StROL-Robot-xR-v0"

    def network_input(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray) -> np.ndarray:
        x, u_h, u_r = (np.asarray(v, dtype=np.float64) for v in (x, u_h, u_r))
        lead = np.broadcast_shapes(x.shape[:-1], u_h.shape[:-1], u_r.shape[:-1])
        x_r = self.dynamics(
            np.broadcast_to(x, (*lead, x.shape[-1])),
            np.zeros((*lead, u_h.shape[-1])),
            np.broadcast_to(u_r, (*lead, u_r.shape[-1])),
        )
        return super().network_input(x_r, np.broadcast_to(u_h, (*lead, u_h.shape[-1])), u_r)


def correction_sizes(task_spec: str, checkpoint: str, n: int = 2000, seed: int = 1000):
    """Quartiles of max_axis |u_H|/a_max over ``n`` corrections drawn exactly as the
    checkpoint's training drew them (its sidecar's TrainConfig, ``sample_batch``): the size of
    the inputs that ĝ learned from, to set beside a participant's pushes."""
    from strol_gym.learners.checkpoint import read_sidecar
    from strol_gym.learners.training import TrainConfig, sample_batch
    from strol_gym.tasks import make_task

    task = make_task(task_spec)
    cfg = dict(read_sidecar(checkpoint)["training"])
    cfg["hidden"] = tuple(cfg["hidden"])
    batch = sample_batch(task, np.random.default_rng(seed), n, TrainConfig(**cfg))
    size = np.abs(batch["u_h"] / task.action_bound).max(axis=-1)
    return np.quantile(size, [0.25, 0.5, 0.75])


def main(argv: list[str] | None = None) -> None:
    """Print the v1 study ĝ's training-correction sizes (docs/fidelity.md, item 5)."""
    for k in (1, 2, 3):
        spec = f"strol_gym.tasks.study:StudyTask{k}V1"
        path = f"strol_gym/pretrained/study{k}-v1_strol.pt"
        q = correction_sizes(spec, path)
        print(f"Task {k}: training max|u_H|/a_max Q1 {q[0]:.2f}, median {q[1]:.2f}, Q3 {q[2]:.2f}")


if __name__ == "__main__":
    main()
