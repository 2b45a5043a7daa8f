"""StROL-Highway-v0: a robot car learns the driving style of the human car behind it."""

from __future__ import annotations

import math
import os
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from highway_env.envs.common.abstract import AbstractEnv
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.graphics import VehicleGraphics
from highway_env.vehicle.kinematics import Vehicle

from strol_gym.compiled import use_fast
from strol_gym.envs.contract import CorrectionEnv, correcting, render_metadata
from strol_gym.envs.highway.road import Car, LaneLookup
from strol_gym.humans.builtin import drawn_teacher
from strol_gym.tasks.highway import N_LANES, HighwayTask, _drawn_kernel

ROAD_LENGTH = 10_000.0  # m; an episode covers well under 1 km


def _row(a: Any, n: int) -> bool:
    """Whether ``a`` is n contiguous float64 numbers (what the compiled correction reads)."""
    return (
        type(a) is np.ndarray and a.dtype == np.float64 and a.shape == (n,) and a.flags.c_contiguous
    )


class HumanVehicle(Car):
    """A highway-env kinematic vehicle driven by the env's ``Human``.

    The env asks the human for u_H = (acceleration, steering) and sets it as the vehicle's
    action, which ``Vehicle.step`` then integrates. Noise and bias are already inside u_H (the
    human adds them). The vehicle keeps no reference to the human: the env holds it.
    """


class HighwayEnv(CorrectionEnv, AbstractEnv):
    """StROL-Highway-v0: a human car with hidden driving preferences θ* behind a robot car.

    ## Description

    The paper's **Highway** setting (StROL, RA-L 2024, "Simulations") on highway-env's road,
    vehicles and renderer. A straight two-lane highway (highway-env frame: x along the road,
    y to the driver's right; left lane centre y = 0, right lane centre y = 4 m). The robot car
    (green, the agent) drives ahead of the human car (blue); both start in the left lane. The
    human car is a :class:`HumanVehicle` driven by a simulated human with hidden reward weights
    θ* over three features φ(x). During the first ``n_corrections`` steps the human's action
    u_H is its *correction*, from which an online learner (``strol_gym.wrappers``) updates the
    robot's estimate θ̂; afterwards u_H = 0 (the human car holds its speed and heading). Both
    cars move by highway-env's kinematic bicycle model (``Vehicle.step``), one integration step
    of ``task.dt`` = 0.5 s per env step (simulation frequency = policy frequency = 2 Hz).

    Features (``HighwayTask``; "T ahead" = predicted 2 s ahead with each car keeping its speed
    and heading; values are O(1)):

    - ``gap`` = −[max(b − 10 m, 4 (10 m − b)) + 2 |a|] / 20 m: distance of the human car from
      the tailgating slot 10 m behind the robot car in its lane, T ahead; b = x_R − x_H (how far
      behind, signed), a = y_R − y_H (how far beside). 0 at the slot; −0.25 ... −1.5 at start.
    - ``speed`` = (v_H − 25 m/s) / 5 m/s: the human car's speed (so g depends on u_H).
    - ``lane_change`` = 1 − |ℓ − 1|, ℓ = (y_H + T v_H sin h_H) / 4 m: the human car's lateral
      position T ahead in lanes (0 = left lane centre, 1 = right lane centre).

    Human models: ``"nominal"`` (eq. M6: the correction that moves θ̂ closest to θ*, the
    model ĝ is trained on), ``"boltzmann"`` (P(u) ∝ exp(β θ*·g)), ``"driver"`` (the constant
    action that maximises Σ θ*·φ over a 2 s horizon of the kinematic model), or your own.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: the robot car's (acceleration, steering), scaled by
    ``task.robot_action_bound`` = (5 m/s², 0.02 rad). Out-of-range actions are clipped; a NaN
    or infinite action raises ``ValueError``.

    ## Observation Space

    ``Dict`` of float32 Boxes (the space never changes):

    - ``"state"`` (8,): exactly the Task state x = (x_R, y_R, v_R, h_R, x_H, y_H, v_H, h_H) in
      m, m, m/s, rad (robot car first).
    - ``"correction"`` (2,): u_H, the human car's (acceleration m/s², steering rad) this step,
      noise and bias included; zeros when the human does not correct (and after reset).
    - ``"theta_hat"`` (3,): the robot's current estimate θ̂ (see ``set_theta_hat``).
    - ``"phi"`` (3,): φ(x), the features of the state.

    Built directly from the two vehicles: no highway-env observation type runs in the loop.

    ## Rewards

    R(x', θ*) = θ*·φ(x'), the human's reward of the state reached. ``info`` carries
    ``"features"`` (name -> value), ``"phi"``, ``"correction"`` (u_H), ``"robot_action"`` (u_R as
    applied, task units), ``"theta_star"`` (the human's current preference, for evaluation
    only), ``"theta_hat"``, ``"is_correction"`` and ``"crashed"``.

    ## Starting State

    Drawn from ``env.np_random`` at reset, in this order: θ* from the prior; the start state
    (``HighwayTask.sample_episode_start``: human car at x ∈ [50, 100] m, robot car 15–40 m
    ahead, both at 20–30 m/s, in the left lane within ±0.5 m (robot) / ±1 m (human) of its
    centre, headings within ±0.02 / ±0.05 rad); the seed of the human's own generator. So two
    envs reset with the same seed give the same θ*, start and human noise draws (paired runs).
    θ̂ starts at the mean of the bimodal prior's modes, (0.55, 1.0, 0.55), unless
    ``set_theta_hat`` is called. ``reset(options={"theta_star": ..., "state": ...})`` overrides
    either draw (the draws still happen, so pairing is kept).

    ## Episode End

    Terminated when the cars collide (highway-env's collision check). Truncated after
    ``max_episode_steps`` steps (10 through ``gymnasium.make``, the paper's 10 learning steps).
    Leaving the road is not terminal.

    ## Arguments

    - ``person``: who corrects, as for StROL-Robot-v0 (``RobotEnv``; ``strol_gym.humans.spec``):
      omitted, "nominal" with σ = ε = 0; a registered name ("driver" is the paper's MPC
      human), a ``HumanSpec`` or a dict of its fields (σ, ε per action axis in units of
      a_max); ``None``: nobody corrects. A value the person does not use raises ValueError.
    - ``prior`` ("bimodal" | "uniform" | a ``Prior`` | array of modes, default "bimodal"):
      P(θ*). "bimodal": modes "tailgate" (1.0, 1.0, 0.1) and "pass on the right"
      (0.1, 1.0, 1.0) with N(0, 0.1²) jitter (see ``strol_gym.tasks.highway`` for the signs);
      "uniform": [−1, 1]³.
    - ``n_corrections`` (int ≥ 0, default 10): steps during which the human corrects.
    - ``max_episode_steps`` (int ≥ 1 or None): through ``gymnasium.make`` this is gymnasium's
      own TimeLimit argument (registered default 10, the paper's 10 learning steps); given to
      ``HighwayEnv`` directly, the env truncates itself after that many steps (default None:
      never).
    - ``render_mode`` (None | "human" | "rgb_array"); ``width``, ``height`` (int in
      [16, 4096], default 600 x 150): frame size in pixels. Headless "rgb_array" needs
      ``SDL_VIDEODRIVER=offscreen`` (set by default if unset; "dummy" renders blank frames).
    - ``task`` (a ``HighwayTask``, its registered name or "module:attr", or None): a variant
      of the setting (its prior is replaced by ``prior``).

    ## Version History

    - v0: initial version.
    """

    # one frame per env step of task.dt = 0.5 s (2 Hz): videos play in real time
    metadata: dict[str, Any] = render_metadata(fps=2)
    time: float
    """Simulated seconds (highway-env starts it as the int 0)."""

    env_id: ClassVar[str] = "StROL-Highway-v0"
    task_cls: ClassVar[type[HighwayTask]] = HighwayTask
    default_corrections: ClassVar[int] = 10
    default_size: ClassVar[tuple[int, int]] = (600, 150)

    def _setup(self) -> None:
        self.task: HighwayTask
        width, height = self.width, self.height
        freq = 1.0 / self.task.dt
        # highway-env's straight road, its closest-lane lookup in plain floats (the same lanes)
        self._network = RoadNetwork.straight_road_network(
            lanes=N_LANES, length=ROAD_LENGTH, speed_limit=None, net=LaneLookup()
        )
        self.robot_vehicle: Vehicle | None = None
        self.human_vehicle: HumanVehicle | None = None
        AbstractEnv.__init__(
            self,
            config={
                "simulation_frequency": freq,
                "policy_frequency": freq,
                "screen_width": width,
                "screen_height": height,
                "centering_position": [0.7, 0.5],
                "scaling": 5.5 * width / 600,
            },
            render_mode=self.render_mode,
        )
        # highway-env's constructor resets once; the episode starts at the caller's reset(),
        # so step() before it raises, as in every strol-gym env.
        self.human = None

    # ------------------------------------------------------------------ spaces, θ̂
    def define_spaces(self) -> None:
        """Fixed spaces; highway-env's observation and action types are not used."""
        state = spaces.Box(-np.inf, np.inf, shape=(self.task.state_dim,), dtype=np.float32)
        self.observation_space = self._observation_space(state)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(self.task.action_dim,), dtype=np.float32)
        self.observation_type = None
        self.action_type = None

    # ------------------------------------------------------------------ the template's hooks
    def draw_starts(
        self, rngs: list[np.random.Generator], human_rngs: bool = True
    ) -> tuple[np.ndarray, list[Any]]:
        """Per generator, the start and then the seed of the human's own generator (None
        instead of the generator unless ``human_rngs``: a vector env whose humans never act
        skips building them)."""
        x0 = self.task.sample_episode_starts(rngs)
        seeds = [int(rng.integers(0, 2**63 - 1)) for rng in rngs]
        return x0, [np.random.default_rng(s) if human_rngs else None for s in seeds]

    def _place_start(self, x0: np.ndarray) -> np.ndarray:
        self.time = 0
        self.done = False
        self._build_scene(x0)
        return self._read_state()

    def _start_info(self) -> dict[str, Any]:
        return {"crashed": self._is_terminated()}

    def _cars(self) -> tuple[Vehicle, HumanVehicle]:
        """The robot's car and the human's: None until the first scene is built (reset)."""
        r, h = self.robot_vehicle, self.human_vehicle
        if r is None or h is None:
            raise RuntimeError("the highway scene is not built yet: call reset() first")
        return r, h

    def _advance(self, u_h: np.ndarray, u_r: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        robot, human = self._cars()
        (h_acc, h_steer), (r_acc, r_steer) = u_h.tolist(), u_r.tolist()
        human.act({"acceleration": h_acc, "steering": h_steer})
        robot.act({"acceleration": r_acc, "steering": r_steer})
        self.road.step(self.task.dt)
        self.time += self.task.dt
        return self._read_state(), {"crashed": self._is_terminated()}

    def _terminated(self) -> bool:
        return self._is_terminated()

    def _human_correction(self, x: np.ndarray, u_r: np.ndarray) -> tuple[np.ndarray, bool]:
        """The contract's; for an eq. M6 teacher (``drawn_teacher``) the draws go straight
        into the compiled correction (``HighwayTask.m6_drawn``'s kernel) through buffers kept
        per person: the draws, numbers and checks of ``SimulatedHuman.act`` and the
        contract's, without their per-call arrays and look-ups."""
        human: Any = self.human  # a SimulatedHuman wherever ``_teacher`` finds a teacher
        if human is None or not correcting(self.steps, self.n_corrections):
            return super()._human_correction(x, u_r)
        teach = self.__dict__.get("_teach")
        if teach is None or teach[0] is not human:  # asked once per episode's person
            teach = self._teach = (human, self._teacher(human))
        found, th = teach[1], self.theta_hat
        if found is None or not use_fast() or not (_row(th, 3) and _row(x, 8) and _row(u_r, 2)):
            return super()._human_correction(x, u_r)
        model, kernel, units, noise, cand, keep, steer, best = found
        human.begin()
        theta_star = np.ascontiguousarray(human.theta_star, dtype=np.float64)
        human.rng.random(out=units)  # the draws of ``NominalModel.drawn_corrections``
        human.rng.standard_normal(out=noise)
        prm = self.task.m6_drawn_params(model.sigma, model.bias)
        out = np.empty((1, 2))
        rows = (x[None], u_r[None], th[None], theta_star[None])
        n = kernel(*rows, units, noise, prm, cand, keep, steer, best, out)
        if n:  # the screen left the choice open: the exact search
            self.task.m6_drawn_left(*rows, noise, prm, cand, keep, steer[:n], best, out)
        u_h = out[0]
        if not all(map(math.isfinite, u_h.tolist())):
            raise ValueError(f"the human's correction must be 2 finite numbers, got {u_h}")
        return u_h, True

    def _teacher(self, human: Any) -> tuple | None:
        """(the teacher's model, the compiled correction, buffers for its uniform and normal
        draws, the candidates, the screen's marks and steering angles, and the picks) where
        ``human`` is an eq. M6 teacher of this env's Task; else None."""
        model = drawn_teacher(human, self.task)
        if model is None or self.task.m6_drawn() is None:
            return None
        k = model.n_candidates
        return (
            model,
            _drawn_kernel(),
            np.empty((1, k, 2)),
            np.empty((1, 2)),
            np.empty((1, k + 1, 2)),
            np.empty((1, k + 1), dtype=np.bool_),
            np.empty(k + 2),
            np.empty(1, dtype=np.int64),
        )

    def _build_scene(self, x0: np.ndarray) -> None:
        """highway-env's road with the two cars at x0. After the first episode the road and the
        cars are reset in place (``Car.restart``: what building them sets, at a fraction of
        the cost), unless something replaced them."""
        xr0, yr0, vr, hr, xh0, yh0, vh, hh = x0.tolist()
        road: Any = self.__dict__.get("road")
        robot, human = self.robot_vehicle, self.human_vehicle
        if (
            type(road) is Road
            and type(robot) is Car
            and type(human) is HumanVehicle
            and robot.reusable(road)
            and human.reusable(road)
            and road.network is self._network
            and road.vehicles == [robot, human]
            and not road.objects
        ):
            road.np_random = self.np_random
            road.record_history = self.config["show_trajectories"]
            road.neighbour_vehicles_connected_lanes = False
            robot.restart([xr0, yr0], hr, vr)
            human.restart([xh0, yh0], hh, vh)
            robot.color, human.color = VehicleGraphics.EGO_COLOR, VehicleGraphics.BLUE
            road.vehicles = [robot, human]
            self.controlled_vehicles = [robot]
            return
        self.road = Road(
            network=self._network,
            np_random=self.np_random,
            record_history=self.config["show_trajectories"],
        )
        robot = Car(self.road, x0[0:2], heading=hr, speed=vr)
        robot.color = VehicleGraphics.EGO_COLOR
        human = HumanVehicle(self.road, x0[4:6], heading=hh, speed=vh)
        human.color = VehicleGraphics.BLUE
        self.road.vehicles = [robot, human]
        self.controlled_vehicles = [robot]
        self.robot_vehicle, self.human_vehicle = robot, human

    def _read_state(self) -> np.ndarray:
        r, h = self._cars()
        # positions as plain floats: the same numbers, without indexing numpy four times
        (r0, r1), (h0, h1) = r.position.tolist(), h.position.tolist()
        return np.array([r0, r1, r.speed, r.heading, h0, h1, h.speed, h.heading], dtype=np.float64)

    # highway-env's hooks, kept meaningful for code that calls them
    def _reset(self) -> None:
        self._build_scene(self.task.sample_episode_start(self.np_random, 1)[0])

    def _reward(self, action: np.ndarray) -> float:
        return float(self.task.reward(self._read_state(), self.theta_star))

    def _is_terminated(self) -> bool:
        r, h = self._cars()
        return bool(r.crashed or h.crashed)

    def _is_truncated(self) -> bool:
        return self._truncated()

    # ------------------------------------------------------------------ render, pickle
    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; "
                'make the env with render_mode="rgb_array" or "human"'
            )
            return None
        if self.render_mode == "rgb_array":
            os.environ.setdefault("SDL_VIDEODRIVER", "offscreen")
            if os.environ["SDL_VIDEODRIVER"] == "dummy":
                gym.logger.warn(
                    "SDL_VIDEODRIVER=dummy makes highway-env skip drawing (blank frames); "
                    "use SDL_VIDEODRIVER=offscreen"
                )
        return super().render()

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["viewer"] = None
        state["_record_video_wrapper"] = None
        return state
