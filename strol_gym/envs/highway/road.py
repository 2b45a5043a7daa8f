"""highway-env's road and cars with two of their per-step questions answered in plain floats:
which lane a car is in (for axis-aligned straight lanes, the env's road) and whether two cars
are clearly too far apart to collide. The same answers, at a fraction of numpy's per-call cost.

Every ``Vehicle.step`` asks the network for the lane closest to the car (``on_state_update``):
highway-env computes each lane's ``distance_with_heading`` with numpy calls on two numbers,
about a fifth of a Highway env step. :class:`LaneLookup` computes the same distances with the
same IEEE operations in plain floats and picks as ``np.argmin`` does (the first minimum, or the
first NaN), so every car lands in the same lane. Only lanes of type ``StraightLane`` whose
direction is (1, 0) take this path: then the dot products of ``local_coordinates`` have one
exact term and a zero (no rounding, whatever order a BLAS sums in). Any other network asks
highway-env's own lookup.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from highway_env.road.lane import StraightLane
from highway_env.road.road import LaneIndex, RoadNetwork
from highway_env.vehicle.kinematics import Vehicle

_Lane = tuple[Any, float, float, float, float, float, float, float, float]
"""A lane's index and its numbers as plain floats: start (2), direction (2), lateral direction
(2), length, heading."""


class LaneLookup(RoadNetwork):
    """A ``RoadNetwork`` whose ``get_closest_lane_index`` runs in plain floats where its lanes
    allow (see the module docstring); its lanes must not change once it is first asked."""

    _lanes: list[_Lane] | None

    def get_closest_lane_index(
        self, position: np.ndarray, heading: float | None = None
    ) -> LaneIndex:
        lanes = self.__dict__.get("_lanes", False)
        if lanes is False:
            lanes = self._lanes = self._plain_lanes()
        if (
            lanes is None
            or heading is None
            or type(position) is not np.ndarray
            or position.dtype != np.float64
        ):
            return super().get_closest_lane_index(position, heading)
        p0, p1 = position.tolist()
        h = float(heading)
        best, low = None, math.inf
        for index, s0, s1, x0, x1, y0, y1, length, lane_heading in lanes:
            # StraightLane.local_coordinates and distance_with_heading (weight 1), op for op
            d0, d1 = p0 - s0, p1 - s1
            s = d0 * x0 + d1 * x1
            r = d0 * y0 + d1 * y1
            angle = abs(((h - lane_heading) + math.pi) % (2 * math.pi) - math.pi)
            dist = abs(r) + max(s - length, 0) + max(0 - s, 0) + 1.0 * angle
            if dist != dist:  # np.argmin stops at the first NaN
                return index
            if best is None or dist < low:
                best, low = index, dist
        return best

    def _plain_lanes(self) -> list[_Lane] | None:
        """The lanes in the order highway-env visits them, as plain floats; None when one is
        not an axis-aligned ``StraightLane`` (then highway-env's lookup runs)."""
        out: list[_Lane] = []
        for _from, to_dict in self.graph.items():
            for _to, lanes in to_dict.items():
                for _id, lane in enumerate(lanes):
                    if type(lane) is not StraightLane or lane.direction.tolist() != [1.0, 0.0]:
                        return None
                    out.append(
                        (
                            (_from, _to, _id),
                            *lane.start.tolist(),
                            *lane.direction.tolist(),
                            *lane.direction_lateral.tolist(),
                            float(lane.length),
                            float(lane.heading),
                        )
                    )
        return out or None


_MARGIN = 1.0 + 1e-9
"""How far (relatively, in squared distance) beyond highway-env's reach a pair must be for the
plain-float check to answer: far more than the few ulps in which its norm and ours may differ."""


class Car(Vehicle):
    """highway-env's kinematic vehicle whose collision check first answers, in plain floats,
    for cars clearly farther apart than highway-env's spherical pre-check allows.

    highway-env's ``_is_colliding`` returns "no collision" when ``np.linalg.norm`` of the
    offset exceeds the reach ``(diagonal + other.diagonal) / 2 + speed · dt``. Here the squared
    offset is compared with the squared reach times ``_MARGIN``: past it the norm exceeds the
    reach whatever order and rounding numpy's norm uses, so the answer is the same; everything
    else (near pairs, non-finite numbers) goes to highway-env's own check."""

    def _is_colliding(self, other: Any, dt: float) -> Any:
        mine, theirs = self.position, getattr(other, "position", None)
        if type(mine) is np.ndarray and type(theirs) is np.ndarray and mine.shape == (2,):
            (a0, a1), (b0, b1) = mine.tolist(), theirs.tolist()
            d0, d1 = b0 - a0, b1 - a1
            reach = (float(self.diagonal) + float(other.diagonal)) / 2 + float(self.speed) * dt
            square = d0 * d0 + d1 * d1
            if 0.0 < reach < 1e150 and math.isfinite(square) and square > reach * reach * _MARGIN:
                return False, False, np.zeros(2)
        return super()._is_colliding(other, dt)
