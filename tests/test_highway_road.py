"""The Highway env's road and cars (``strol_gym.envs.highway.road``): the closest-lane lookup and
the far-pair collision check in plain floats give highway-env's own answers."""

from __future__ import annotations

from collections import deque

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


def test_near_pairs_apart_along_an_axis_get_highway_envs_answer(monkeypatch):
    """The second pre-check (apart along one of the car's own axes) answers as highway-env's
    rectangle test would, and takes most pairs that are within the spherical reach but apart."""
    _, network = _networks()
    road = Road(network=network, np_random=np.random.default_rng(0))
    rng = np.random.default_rng(2)
    asked = []
    check = Vehicle._is_colliding

    def counting(self, other, dt):
        asked.append(1)
        return check(self, other, dt)

    answers = set()
    for _ in range(3000):
        a = Car(
            road, rng.uniform(-5, 5, 2), heading=rng.uniform(-0.3, 0.3), speed=rng.uniform(0, 35)
        )
        d = rng.uniform(0.0, a.diagonal + a.speed * 0.5)  # within the spherical reach
        angle = rng.uniform(0, 2 * np.pi)
        b = Car(
            road,
            a.position + d * np.array([np.cos(angle), np.sin(angle)]),
            heading=rng.uniform(-0.3, 0.3),
            speed=rng.uniform(0, 35),
        )
        monkeypatch.setattr(Vehicle, "_is_colliding", counting)
        ours = a._is_colliding(b, 0.5)
        monkeypatch.setattr(Vehicle, "_is_colliding", check)
        theirs = Vehicle._is_colliding(a, b, 0.5)
        assert ours[:2] == theirs[:2]
        assert (ours[2] is None) == (theirs[2] is None)
        if ours[2] is not None:
            assert ours[2].tobytes() == theirs[2].tobytes()
        answers.add(ours[:2])
    assert answers >= {(False, False), (False, True), (True, True)}  # apart, impact, crash
    assert 500 < len(asked) < 2900  # some pairs answered here, the others by highway-env


def test_a_car_steps_as_highway_envs_vehicle():
    """``Car.step`` in plain floats: highway-env's ``Vehicle.step`` to the bit, crashed, with an
    impact, at the speed limits and with extreme steering included."""
    _, network = _networks()
    road = Road(network=network, np_random=np.random.default_rng(0))
    rng = np.random.default_rng(3)
    for i in range(3000):
        state = dict(heading=rng.uniform(-3, 3), speed=rng.choice([rng.uniform(-45, 45), 0.0]))
        position = rng.uniform([-20, -8], [1e4, 12])
        ours = Car(road, position.copy(), **state)
        theirs = Vehicle(road, position.copy(), **state)
        action = {
            "acceleration": rng.uniform(-10, 10),
            "steering": rng.choice([rng.uniform(-0.05, 0.05), rng.uniform(-1.5, 1.5), 0.0]),
        }
        for v in (ours, theirs):
            v.act(dict(action))
            v.crashed = i % 7 == 0
            v.impact = np.array([0.3, -0.1]) if i % 11 == 0 else None
        for _ in range(3):
            ours.step(0.5)
            theirs.step(0.5)
            assert ours.position.tobytes() == theirs.position.tobytes()
            for name in ("heading", "speed"):  # the bits, the sign of a zero included
                assert (
                    np.float64(getattr(ours, name)).tobytes()
                    == np.float64(getattr(theirs, name)).tobytes()
                )
            assert ours.lane_index == theirs.lane_index and ours.lane is theirs.lane
            assert ours.crashed == theirs.crashed
            assert ours.action == theirs.action


def _same_attributes(mine: object, fresh: object) -> None:
    assert vars(mine).keys() == vars(fresh).keys()
    for name, value in vars(fresh).items():
        got = vars(mine)[name]
        assert type(got) is type(value), name
        if isinstance(value, np.ndarray):
            assert got.dtype == value.dtype and got.tobytes() == value.tobytes(), name
        elif isinstance(value, deque):
            assert list(got) == list(value) and got.maxlen == value.maxlen, name
        else:
            assert got == value, name


def test_a_new_episode_restarts_the_cars_as_building_them_would():
    """After an episode that ended in a crash (impact, crashed flags, a changed action), a reset
    keeps the road and the cars, each attribute as a newly built road and cars would have it."""
    from strol_gym.envs.highway.env import HighwayEnv, HumanVehicle

    env = HighwayEnv(n_corrections=0)
    env.reset(seed=0, options={"state": [112.0, 0.0, 20.0, 0.0, 100.0, 0.0, 35.0, 0.0]})
    road, robot, human = env.road, env.robot_vehicle, env.human_vehicle
    for _ in range(10):
        *_, term, _, _ = env.step(np.array([-1.0, 0.3], dtype=np.float32))
        if term:
            break
    assert term and robot.crashed and robot.action["steering"] != 0
    robot.log.append("seen")
    env.reset(seed=3)
    assert (env.road, env.robot_vehicle, env.human_vehicle) == (road, robot, human)
    x = env._x
    fresh_road = Road(network=road.network, np_random=env.np_random, record_history=False)
    fresh = [
        Car(fresh_road, x[0:2], heading=float(x[3]), speed=float(x[2])),
        HumanVehicle(fresh_road, x[4:6], heading=float(x[7]), speed=float(x[6])),
    ]
    fresh[0].color, fresh[1].color = robot.color, human.color
    fresh_road.vehicles = fresh
    for mine, new in ((robot, fresh[0]), (human, fresh[1])):
        mine_road, mine.road = mine.road, fresh_road  # the one attribute that must differ
        _same_attributes(mine, new)
        mine.road = mine_road
    road_vars = dict(vars(road), vehicles=fresh)
    assert road_vars.keys() == vars(fresh_road).keys()
    assert all(road_vars[k] is v or road_vars[k] == v for k, v in vars(fresh_road).items())
