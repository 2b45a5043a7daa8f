"""StROL-Highway-v0 as a native vector env: N two-car highways, their dynamics batched in numpy."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from highway_env.vehicle.kinematics import Vehicle

from strol_gym.envs.highway.env import HighwayEnv
from strol_gym.envs.vector import VectorCorrectionEnv

_CORNERS = np.array(
    [
        [-Vehicle.LENGTH / 2, -Vehicle.WIDTH / 2],
        [-Vehicle.LENGTH / 2, +Vehicle.WIDTH / 2],
        [+Vehicle.LENGTH / 2, +Vehicle.WIDTH / 2],
        [+Vehicle.LENGTH / 2, -Vehicle.WIDTH / 2],
    ]
)


def _polygon(px, py, h):
    """highway-env's ``RoadObject.polygon`` for B cars: corners (B, 4, 2), not closed."""
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    cx, cy = _CORNERS[:, 0], _CORNERS[:, 1]
    return np.stack([c * cx - s * cy + px[:, None], s * cx + c * cy + py[:, None]], axis=-1)


def rectangle_test(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """highway-env's ``Vehicle._is_colliding`` rectangle test (``utils.are_polygons_intersecting``
    on the two cars' rectangles and displacements over ``dt``), for B states (B, 8) at once:
    (intersecting (B,), will intersect (B,), translation (B, 2); zero where it would be None).

    The same steps over the same 8 edge normals, in the same order; where the reference stops
    early (both tests already false) the translation is not used, so none of its later edges
    can change a result.
    """
    b = len(x)
    poly = (_polygon(x[:, 0], x[:, 1], x[:, 3]), _polygon(x[:, 4], x[:, 5], x[:, 7]))
    disp = []
    for i in (0, 4):
        v, h = x[:, i + 2], x[:, i + 3]
        disp.append(np.stack([v * np.cos(h), v * np.sin(h)], axis=-1) * dt)
    rel = disp[0] - disp[1]
    centre = poly[0].mean(axis=1) - poly[1].mean(axis=1)
    intersecting = np.ones(b, dtype=bool)
    will = np.ones(b, dtype=bool)
    min_distance = np.full(b, np.inf)
    axis = np.zeros((b, 2))

    def interval_distance(min_a, max_a, min_b, max_b):
        return np.where(min_a < min_b, min_b - max_a, min_a - max_b)

    for p in poly:
        for e in range(4):
            p1, p2 = p[:, e], p[:, (e + 1) % 4]
            normal = np.stack([-p2[:, 1] + p1[:, 1], p2[:, 0] - p1[:, 0]], axis=-1)
            normal /= np.sqrt(np.einsum("bi,bi->b", normal, normal))[:, None]
            proj_a = np.einsum("bki,bi->bk", poly[0], normal)
            proj_b = np.einsum("bki,bi->bk", poly[1], normal)
            min_a, max_a = proj_a.min(axis=1), proj_a.max(axis=1)
            min_b, max_b = proj_b.min(axis=1), proj_b.max(axis=1)
            intersecting &= ~(interval_distance(min_a, max_a, min_b, max_b) > 0)
            vp = np.einsum("bi,bi->b", normal, rel)
            min_a = np.where(vp < 0, min_a + vp, min_a)
            max_a = np.where(vp < 0, max_a, max_a + vp)
            distance = interval_distance(min_a, max_a, min_b, max_b)
            will &= ~(distance > 0)
            closer = np.abs(distance) < min_distance
            min_distance = np.where(closer, np.abs(distance), min_distance)
            sign = np.where(np.einsum("bi,bi->b", centre, normal) > 0, 1.0, -1.0)
            axis = np.where(closer[:, None], sign[:, None] * normal, axis)
    translation = np.where(will[:, None], min_distance[:, None] * axis, 0.0)
    return intersecting, will, translation


class VectorHighwayEnv(VectorCorrectionEnv):
    """``gymnasium.make_vec("StROL-Highway-v0", num_envs=N)``: N Highway envs in one process.

    Sub-env i is the single ``StROL-Highway-v0`` made with the same arguments and reset with
    the same seed (see ``strol_gym.envs.vector``). Both cars move by the Task's batched
    kinematic bicycle model (``HighwayTask.dynamics``, highway-env's ``Vehicle.step`` written
    once for arrays). Collisions are highway-env's: a batched distance pre-check, then, for the
    pairs of cars close enough, highway-env's rectangle test (``Vehicle._is_colliding``),
    including its "will intersect" impact, which pushes the cars apart on the next step and
    crashes them then (``rectangle_test``: highway-env's algorithm on arrays). A crash
    terminates the sub-env, as in the single env. Arguments are the single env's
    (``render_mode`` must be None) plus ``num_envs``; info adds ``crashed``.
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
        if len(close):
            intersecting, will, transition = rectangle_test(x[close], dt)
            self._impact[rows[close[will]]] = transition[will]
            self._has_impact[rows[close[will]]] = True
            crashed[close[intersecting]] = True
        return x, crashed.copy(), {"crashed": crashed}
