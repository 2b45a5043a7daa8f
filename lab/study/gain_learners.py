"""Learners for the never-moving learner check (a ``--plugin`` for ``strol-bench study``).

``still``: a Gradient learner whose update returns θ̂ unchanged (a robot that never learns).
``one-x1.5``, ``one-x3``, ``one-x6``: One with its step scaled by 1.5, 3 and 6, to see how far
One must move θ̂ before a reacting person corrects the never-learning robot more often
(1.5: the authors' gain, α 1 on 3 × the logged step, over v2's α 2 on the whole push).

    strol-bench study --users 4 --learners one,still,one-x1.5,one-x3,one-x6 \\
        --plugin lab/study/gain_learners.py --out OUT --jobs 2
"""

from __future__ import annotations

import numpy as np

from strol_gym.learners.registry import register_learner
from strol_gym.learners.rules import GradientLearner, OneLearner


class Still(GradientLearner):
    """Never moves θ̂."""

    name = "still"

    def update(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None = None) -> np.ndarray:
        return np.asarray(self.theta).copy()


class OneX15(OneLearner):
    """One with its step times ``gain``."""

    name = "one-x1.5"
    gain = 1.5

    def direction(self, x, u_h, u_r, theta) -> np.ndarray:
        return self.gain * super().direction(x, u_h, u_r, theta)


class OneX3(OneX15):
    name = "one-x3"
    gain = 3.0


class OneX6(OneX15):
    name = "one-x6"
    gain = 6.0


register_learner("still", Still, display="Still")
for _cls in (OneX15, OneX3, OneX6):
    register_learner(_cls.name, _cls, display=f"One x{_cls.gain:g}")
