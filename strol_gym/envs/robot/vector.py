"""StROL-Robot-v0 as a native vector env: N Panda arms, their IK and humans batched in numpy."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from strol_gym.envs.panda.ik import IK_ITERS
from strol_gym.envs.panda.ik_batched import BatchedPandaIK
from strol_gym.envs.panda.model import Q_HOME
from strol_gym.envs.robot.env import RobotEnv
from strol_gym.envs.vector import VectorCorrectionEnv


class VectorRobotEnv(VectorCorrectionEnv):
    """``gymnasium.make_vec("StROL-Robot-v0", num_envs=N)``: N Robot envs in one process.

    Sub-env i is the single ``StROL-Robot-v0`` made with the same arguments and reset with the
    same seed (see ``strol_gym.envs.vector``); the arms' IK runs for all of them at once
    (``BatchedPandaIK``), the arm positioned kinematically as in the single env. Arguments are
    the single env's (``render_mode`` must be None) plus ``num_envs``. Info adds ``target`` and
    ``ik_error`` as the single env's does.
    """

    single_env_cls: ClassVar[type] = RobotEnv
    extra_info: ClassVar[tuple[str, ...]] = ("target", "ik_error")

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        super().__init__(num_envs, **kwargs)
        self.template: RobotEnv
        self.ik = BatchedPandaIK(self.template.ik, self.num_envs)
        self._x[:] = self.ik.ee

    def _place_rows(self, rows: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, dict]:
        """``RobotEnv.move_to`` for each row: from the nearest seed, 2 x IK_ITERS iterations."""
        ref = self.ik.reference(x0)
        none = np.isnan(ref[:, 0])
        ref[none] = Q_HOME
        self.ik.q[rows] = ref
        self.ik.forward(rows)
        self.ik.solve(x0, rows, iters=2 * IK_ITERS)
        x = self.ik.ee[rows]
        return x, {"target": x.copy(), "ik_error": np.zeros(len(rows))}

    def _step_rows(self, rows, u_h, u_r):
        target = self.task.dynamics(self._x[rows], u_h, u_r)
        err = self.ik.solve(target, rows)
        ee = self.ik.ee  # a fresh array: every row's, or the rows' own
        return (
            ee if len(rows) == self.num_envs else ee[rows],
            np.zeros(len(rows), dtype=bool),
            {
                "target": target,
                "ik_error": err,
            },
        )
