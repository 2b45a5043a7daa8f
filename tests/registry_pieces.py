"""User pieces for the registry tests, importable by name (as a worker process needs)."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from strol_gym.humans import NominalHuman
from strol_gym.learners.rules import GradientLearner
from strol_gym.tasks.robot import RobotTask

SEEN: list[dict] = []


class HalfGradient(GradientLearner):
    """Gradient with half its step: a learner of one's own."""

    def update(self, x, u_h, u_r=None):
        before = self.theta.copy()
        after = super().update(x, u_h, u_r)
        self.theta = before + 0.5 * (after - before)
        return self.theta


def shy_human(task, theta_star, rng, sigma=0.0, bias=0.0, beta=1.0, shyness=0.5):
    """A human who corrects with ``shyness`` times the eq. M6 correction (records its args)."""
    SEEN.append({"sigma": sigma, "bias": bias, "beta": beta, "shyness": shyness})
    inner = NominalHuman(task, theta_star, rng, sigma=sigma, bias=bias)

    class Shy:
        def __init__(self):
            self.theta_star = inner.theta_star

        def act(self, x, u_r, theta_hat):
            return shyness * inner.act(x, u_r, theta_hat)

    return Shy()


@dataclasses.dataclass(frozen=True, eq=False)
class NearCupTask(RobotTask):
    """The Robot setting with the cup moved 18 cm closer to the plate."""

    task_id: ClassVar[str] = "Test-NearCup-v0"

    cup: np.ndarray = dataclasses.field(default_factory=lambda: np.array([0.60, -0.30, 0.10]))
