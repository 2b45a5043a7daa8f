"""The Highway env's road and cars (``strol_gym.envs.highway.road``): the closest-lane lookup and
the far-pair collision check in plain floats give highway-env's own answers."""

from __future__ import annotations

import numpy as np
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.kinematics import Vehicle

from strol_gym.envs.highway.env import ROAD_LENGTH
from strol_gym.envs.highway.road import Car, LaneLookup
from strol_gym.tasks.highway import N_LANES

EDGES = [0.0, -0.0, 2.0, 2.0 + 4e-16, 2.0 - 4e-16, 4.0, -1e-300, ROAD_LENGTH, 1e4 + 0.1, -0.1]


def _networks() -> tuple[RoadNetwork, RoadNetwork]:
    def road(net=None):
        return RoadNetwork.straight_road_network(
            lanes=N_LANES, length=ROAD_LENGTH, speed_limit=None, net=net
        )

    return road(), road(LaneLookup())


def test_the_closest_lane_is_highway_envs_own():
    theirs, ours = _networks()
    rng = np.random.default_rng(0)
    cases = [
        (np.array(rng.choice(EDGES, 2)), rng.choice([*EDGES, np.pi, -3.0])) for _ in range(3000)
    ]
    cases += [
        (np.array([x, y]), h) for x, y, h in rng.uniform([-50, -6, -4], [1e4, 10, 4], (3000, 3))
    ]
    cases += [
        (np.array([np.nan, 1.0]), 0.0),
        (np.array([5.0, np.inf]), 0.1),
        (np.array([5.0, 1.0]), np.nan),
    ]
    with np.errstate(invalid="ignore"):
        for position, heading in cases:
            heading = np.float64(heading)
            assert ours.get_closest_lane_index(position, heading) == theirs.get_closest_lane_index(
                position, heading
            )
    assert ours._lanes is not None  # the plain-float path ran


def test_a_network_with_other_lanes_asks_highway_env():
    net = RoadNetwork.straight_road_network(lanes=2, angle=0.3, net=LaneLookup())
    theirs = RoadNetwork.straight_road_network(lanes=2, angle=0.3)
    position = np.array([30.0, 12.0])
    assert net.get_closest_lane_index(position, 0.2) == theirs.get_closest_lane_index(position, 0.2)
    assert net._lanes is None


def test_far_pairs_are_ruled_out_with_highway_envs_answer(monkeypatch):
    _, network = _networks()
    road = Road(network=network, np_random=np.random.default_rng(0))
    rng = np.random.default_rng(1)
    reach = Car(road, [0.0, 0.0]).diagonal  # two cars at rest: the reach is one diagonal
    far = near = 0
    asked = []
    check = Vehicle._is_colliding

    def counting(self, other, dt):
        asked.append(1)
        return check(self, other, dt)

    for _ in range(3000):
        a = Car(
            road, rng.uniform(-5, 5, 2), heading=rng.uniform(-0.3, 0.3), speed=rng.uniform(0, 35)
        )
        # around the reach, within a few ulps of it, and far off
        d = reach + a.speed * 0.5 + rng.choice([rng.uniform(-3, 3), rng.normal(0, 1e-14), 50.0])
        angle = rng.uniform(0, 2 * np.pi)
        b = Car(
            road, a.position + d * np.array([np.cos(angle), np.sin(angle)]), heading=0.1, speed=20.0
        )
        monkeypatch.setattr(Vehicle, "_is_colliding", counting)
        ours = a._is_colliding(b, 0.5)
        monkeypatch.setattr(Vehicle, "_is_colliding", check)
        theirs = Vehicle._is_colliding(a, b, 0.5)
        assert ours[:2] == theirs[:2]
        assert np.asarray(ours[2]).tobytes() == np.asarray(theirs[2]).tobytes()
        far += not theirs[1]
        near += bool(theirs[1])
    assert far > 1000 and near > 20  # both answers came up
    assert 0 < len(asked) < 3000 - far / 2  # near pairs went to highway-env, most far ones not
