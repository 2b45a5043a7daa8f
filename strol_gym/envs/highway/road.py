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
from highway_env.road.road import LaneIndex, Road, RoadNetwork
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
        return self.closest_lane(lanes, p0, p1, float(heading))

    @staticmethod
    def closest_lane(lanes: list[_Lane], p0: float, p1: float, h: float) -> LaneIndex:
        """The closest of ``lanes`` (``_plain_lanes``) to the position (p0, p1) at heading h."""
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

_SPARE = 1e-3
"""Metres added to the reach of the second pre-check (``Car._is_colliding``): far more than the
rounding of highway-env's rectangle test on coordinates within ``_LARGE``."""

_LARGE = 1e6
"""Coordinates, speeds and sizes beyond which the plain-float checks leave the answer to
highway-env (so that rounding stays far below ``_SPARE``)."""


def _within(*values: float) -> bool:
    """Every value finite and within ``_LARGE`` in magnitude (False for NaN)."""
    return all(abs(v) < _LARGE for v in values)


class Car(Vehicle):
    """highway-env's kinematic vehicle, its per-step work in plain floats where it gives the
    same numbers: ``step`` (the kinematic bicycle model) and two collision pre-checks.

    highway-env's ``_is_colliding`` returns "no collision" when ``np.linalg.norm`` of the
    offset exceeds the reach ``(diagonal + other.diagonal) / 2 + speed · dt``. Here the squared
    offset is compared with the squared reach times ``_MARGIN``: past it the norm exceeds the
    reach whatever order and rounding numpy's norm uses, so the answer is the same. A second
    pre-check rules out pairs that highway-env's rectangle test (``are_polygons_intersecting``)
    would find apart: along one of this car's own axes (the first normals it tries) the
    centres are at least |d|/√2 apart, each car's projection is at most half its diagonal, and
    the relative displacement over dt closes the gap by at most its length; beyond
    √2 (half the two diagonals + that length) + ``_SPARE`` the axis separates the cars now and
    after, and the test answers (False, False, None) (for pairs clearly within the spherical
    reach: the rest is highway-env's to answer, its translation a zero vector). Everything
    else (near pairs, non-finite or huge numbers) goes to highway-env's own check."""

    heading: float
    speed: float

    def _is_colliding(self, other: Any, dt: float) -> Any:
        mine, theirs = self.position, getattr(other, "position", None)
        if type(mine) is np.ndarray and type(theirs) is np.ndarray and mine.shape == (2,):
            (a0, a1), (b0, b1) = mine.tolist(), theirs.tolist()
            d0, d1 = b0 - a0, b1 - a1
            half = (float(self.diagonal) + float(other.diagonal)) / 2
            speed = float(self.speed)
            reach = half + speed * dt
            square = d0 * d0 + d1 * d1
            if 0.0 < reach < 1e150 and math.isfinite(square) and square > reach * reach * _MARGIN:
                return False, False, np.zeros(2)
            rel = self._relative_displacement(other, dt)
            if rel is not None and _within(a0, a1, b0, b1, half):
                far = math.sqrt(2.0) * (half + rel) + _SPARE
                # ... and clearly within the spherical reach (else highway-env may answer
                # there, with another "no translation")
                if square > far * far and 0.0 < reach and square * _MARGIN < reach * reach:
                    return False, False, None
        return super()._is_colliding(other, dt)

    def _relative_displacement(self, other: Any, dt: float) -> float | None:
        """|v_self − v_other| dt in plain floats, or None when a number is not a plain finite
        one within ``_LARGE`` (an obstacle, a car of another kind)."""
        if not isinstance(other, Vehicle):
            return None
        try:
            v, h = float(self.speed), float(self.heading)
            w, g = float(other.speed), float(other.heading)
        except (TypeError, ValueError):
            return None
        if not _within(v, h, w, g, dt):
            return None
        return math.hypot(
            v * math.cos(h) - w * math.cos(g), v * math.sin(h) - w * math.sin(g)
        ) * abs(dt)

    def restart(self, position: list[float], heading: float, speed: float) -> None:
        """This car as ``Car(self.road, position, heading, speed)`` builds it (a new episode on
        the same road), in place: every attribute highway-env's constructors set, with the
        values they set; the position array and the history keep their objects (zeroed and
        emptied). What a constructor computes from constants (``diagonal``) stays; the position
        must be the float64 pair a constructor makes (``reusable``)."""
        self.position[0], self.position[1] = position
        self.prediction_type = "constant_steering"  # the constructors' default
        self.heading = heading
        self.speed = speed
        network = self.road.network
        self.lane_index = network.get_closest_lane_index(self.position, heading)
        self.lane = network.get_lane(self.lane_index)
        self.collidable = self.solid = self.check_collisions = True
        self.crashed = self.hit = False
        self.impact = None
        self.action = {"steering": 0, "acceleration": 0}
        log: list[Any] = []  # a new list, as the constructor's
        self.log = log
        self.history.clear()

    def reusable(self, road: Any) -> bool:
        """Whether ``restart`` can stand for building this car anew on ``road``: its own class
        on that road, its position still a float64 pair."""
        position = self.position
        return (
            self.road is road
            and type(position) is np.ndarray
            and position.dtype == np.float64
            and position.shape == (2,)
        )

    def step(self, dt: float) -> None:
        """highway-env's ``Vehicle.step``, op for op in plain floats (its sine and cosine are the
        C library's, as numpy's float64 ones; the steering angle β = arctan(½ tan δ) by numpy,
        whose tangent and arctangent are its own). An impact or a position that is not a
        float64 pair takes highway-env's own step."""
        position = self.position
        if (
            self.impact is not None
            or type(position) is not np.ndarray
            or position.dtype != np.float64
            or position.shape != (2,)
        ):
            super().step(dt)
            return
        self.clip_actions()
        action = self.action
        beta = np.arctan(1 / 2 * np.tan(action["steering"]))
        speed, heading = self.speed, self.heading
        p0, p1 = position.tolist()
        angle = float(heading + beta)
        p0, p1 = position[0], position[1] = (
            p0 + speed * math.cos(angle) * dt,
            p1 + speed * math.sin(angle) * dt,
        )
        self.heading = heading = heading + speed * math.sin(beta) / (self.LENGTH / 2) * dt
        self.speed = speed + action["acceleration"] * dt
        road = self.road
        network = road.network if type(road) is Road else None
        if type(network) is not LaneLookup:
            self.on_state_update()
            return
        lanes = network.__dict__.get("_lanes")
        if not lanes or type(self).on_state_update is not Vehicle.on_state_update:
            self.on_state_update()
            return
        # ``Vehicle.on_state_update``: the lane looked up from the numbers just computed
        self.lane_index = LaneLookup.closest_lane(lanes, p0, p1, float(heading))
        self.lane = network.get_lane(self.lane_index)
        if road.record_history:
            self.history.appendleft(self.create_from(self))
