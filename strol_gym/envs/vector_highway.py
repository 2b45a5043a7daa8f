"""StROL-Highway-v0 as a native vector env: N two-car highways, their dynamics batched in numpy."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from highway_env.vehicle.kinematics import Vehicle

from strol_gym.envs.highway import HighwayEnv
from strol_gym.envs.vector_base import VectorCorrectionEnv


class VectorHighwayEnv(VectorCorrectionEnv):
    """``gymnasium.make_vec("StROL-Highway-v0", num_envs=N)``: N Highway envs in one process.

    Sub-env i is the single ``StROL-Highway-v0`` made with the same arguments and reset with
    the same seed (see ``strol_gym.envs.vector_base``). Both cars move by the Task's batched
    kinematic bicycle model (``HighwayTask.dynamics``, highway-env's ``Vehicle.step`` written
    once for arrays). Collisions are highway-env's: a batched distance pre-check, then, for the
    few pairs of cars close enough, highway-env's own rectangle test (``Vehicle._is_colliding``),
    including its "will intersect" impact, which pushes the cars apart on the next step and
    crashes them then. A crash terminates the sub-env, as in the single env. Arguments are the
    single env's (``render_mode`` must be None) plus ``num_envs``; info adds ``crashed``.
    """

    single_env_cls: ClassVar[type] = HighwayEnv
    extra_info: ClassVar[tuple[str, ...]] = ("crashed",)

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        super().__init__(num_envs, **kwargs)
        self.template: HighwayEnv
        # Pending highway-env impacts (robot car's; the human car's is its negative).
        self._impact = np.zeros((self.num_envs, 2))
        self._has_impact = np.zeros(self.num_envs, dtype=bool)
        self._diagonal = float(np.hypot(Vehicle.LENGTH, Vehicle.WIDTH))

    def _draw_episode(self, rng):
        theta_star = self.task.prior.sample(rng, 1)[0]
        x0 = self.task.sample_episode_start(rng, 1)[0]
        human_rng = np.random.default_rng(int(rng.integers(0, 2**63 - 1)))
        return theta_star, x0, human_rng

    def _place_rows(self, rows: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, dict]:
        self._impact[rows] = 0.0
        self._has_impact[rows] = False
        return x0.copy(), {"crashed": np.zeros(len(rows), dtype=bool)}

    def _step_rows(self, rows, u_h, u_r):
        x = self.task.dynamics(self._x[rows], u_h, u_r)
        crashed = self._has_impact[rows].copy()
        if crashed.any():  # last step's "will intersect": pushed apart, and crashed
            hit = rows[crashed]
            x[crashed, 0:2] += self._impact[hit] / 2
            x[crashed, 4:6] += -self._impact[hit] / 2
            self._has_impact[hit] = False
        # highway-env's spherical pre-check (robot car first: its speed sets the margin) ...
        dt = self.task.dt
        dist = np.hypot(x[:, 4] - x[:, 0], x[:, 5] - x[:, 1])
        near = ~(dist > self._diagonal + x[:, 2] * dt)
        # ... and a second one it implies: its rectangle test only looks along the two cars'
        # axes, and along one of the robot car's axes the centres are at least |d|/√2 apart;
        # beyond √2 (diagonal + |Δv| dt) that axis separates the cars now and after the
        # relative displacement, so the test would answer (False, False). A millimetre spare.
        dvx = x[:, 2] * np.cos(x[:, 3]) - x[:, 6] * np.cos(x[:, 7])
        dvy = x[:, 2] * np.sin(x[:, 3]) - x[:, 6] * np.sin(x[:, 7])
        reach = np.sqrt(2.0) * (self._diagonal + np.hypot(dvx, dvy) * dt) + 1e-3
        close = np.flatnonzero(near & ~(dist > reach))
        for k in close:
            robot = Vehicle(None, x[k, 0:2].copy(), heading=x[k, 3], speed=x[k, 2])
            human = Vehicle(None, x[k, 4:6].copy(), heading=x[k, 7], speed=x[k, 6])
            intersecting, will_intersect, transition = robot._is_colliding(human, dt)
            if will_intersect:
                self._impact[rows[k]] = transition
                self._has_impact[rows[k]] = True
            if intersecting:
                crashed[k] = True
        return x, crashed.copy(), {"crashed": crashed}
