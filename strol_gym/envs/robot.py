"""StROL-Robot-v0: a 7-DoF Franka Panda in MuJoCo learns where a human wants its gripper to go."""

from __future__ import annotations

import functools
import importlib.resources
import importlib.util
import os
from pathlib import Path
from typing import Any, ClassVar

# MuJoCo picks its OpenGL backend when it is first imported: default to headless EGL when there
# is no display (set MUJOCO_GL yourself to override, e.g. osmesa).
if "MUJOCO_GL" not in os.environ and not (
    os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
):
    os.environ["MUJOCO_GL"] = "egl"
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from strol_gym.envs.interaction import CorrectionEnvMixin, HumanFactory, int_arg
from strol_gym.humans import Human
from strol_gym.priors import Prior
from strol_gym.tasks.robot import RobotTask

# ---------------------------------------------------------------------------------- geometry
TABLE_TOP = 0.75
"""World height of the table top, i.e. of the task frame's origin (metres)."""
BASE_IN_TASK = np.array([0.05, -0.10, 0.10])
"""The Panda's base in the task frame: 10 cm behind the workspace's near face, centred on its
y range and on a 10 cm pedestal. Chosen (by a reachability search over base positions) so that
IK reaches every point of RobotTask's workspace box, the gripper pointing down (median tilt 3°
over a grid of the box, 90th percentile 8°, up to ~50° next to the base and at the far bottom
corners)."""
Q_HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 0.0, 0.785])
"""Gripper down: joint 6 of this model is offset by −π/2 from the real Panda's."""
N_ARM = 7
FINGER_OPEN = 0.04
EE_SITE = "end_effector"
SEED_GRID = (9, 11, 8)
"""IK seed table resolution over the workspace box (x, y, z)."""

# ---------------------------------------------------------------------------------- IK
IK_ITERS = 6
"""Damped-least-squares iterations per env step (stops early below IK_TOL)."""
IK_TOL = 2e-4
"""Position tolerance of the IK, metres."""
IK_DAMPING = 0.02
IK_ORIENT_GAIN = 0.3
"""Gain of the gripper-down term, which acts only in the null space of the position task."""
IK_POSTURE_GAIN = 0.1
"""Gain of the pull towards the seed table's posture (null space of the position task)."""
IK_RECOVER = 5.0
"""Restart from the reference posture when the error exceeds IK_RECOVER x IK_TOL."""


def franka_assets_dir() -> Path:
    """gymnasium-robotics' shipped Franka Panda model files (Apache-2.0)."""
    spec = importlib.util.find_spec("gymnasium_robotics")
    if spec is None or spec.origin is None:
        raise ImportError(
            "StROL-Robot-v0 needs gymnasium-robotics (pip install gymnasium-robotics)"
        )
    path = Path(spec.origin).parent / "envs" / "assets" / "kitchen_franka" / "franka_assets"
    if not (path / "chain.xml").exists():
        raise FileNotFoundError(f"Franka Panda model files not found in {path}")
    return path


def _fmt(v: Any) -> str:
    return " ".join(f"{float(a):.6g}" for a in np.atleast_1d(v))


def _look_at(eye: np.ndarray, target: np.ndarray) -> str:
    """MuJoCo camera xyaxes for a camera at ``eye`` looking at ``target`` (z up)."""
    f = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(f, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return _fmt(np.concatenate([x, np.cross(x, f)]))


def scene_xml(task: RobotTask, offwidth: int = 640, offheight: int = 480) -> str:
    """The MJCF of the scene for ``task``, built at runtime around the Franka model files."""
    template = importlib.resources.files("strol_gym").joinpath("assets/robot_scene.xml")
    lift = np.array([0.0, 0.0, TABLE_TOP])
    low, high = task.workspace_low, task.workspace_high
    base = BASE_IN_TASK + lift
    table_lo = np.minimum(low, BASE_IN_TASK)[:2] - 0.15
    table_hi = high[:2] + 0.15
    center = 0.5 * (low + high) + lift
    eye = center + np.array([1.55, -1.05, 0.75])
    values = {
        "FRANKA": str(franka_assets_dir()),
        "OFFWIDTH": str(int(offwidth)),
        "OFFHEIGHT": str(int(offheight)),
        "CAM_POS": _fmt(eye),
        "CAM_XYAXES": _look_at(eye, center - np.array([0.0, 0.0, 0.12])),
        "TABLE_POS": _fmt([*(0.5 * (table_lo + table_hi)), 0.5 * TABLE_TOP]),
        "TABLE_SIZE": _fmt([*(0.5 * (table_hi - table_lo)), 0.5 * TABLE_TOP]),
        "PEDESTAL_POS": _fmt(base - [0.0, 0.0, 0.5 * BASE_IN_TASK[2]]),
        "PEDESTAL_SIZE": _fmt([0.09, max(0.5 * BASE_IN_TASK[2], 1e-3)]),
        "PLATE_POS": _fmt(task.plate + lift + [0.0, 0.0, 0.005]),
        "CUP_POS": _fmt([*task.cup[:2], TABLE_TOP + 0.5 * max(task.cup[2], 0.02)]),
        "CUP_SIZE": _fmt([0.04, 0.5 * max(task.cup[2], 0.02)]),
        "BOX_POS": _fmt(center),
        "BOX_SIZE": _fmt(0.5 * (high - low)),
        "BASE_POS": _fmt(base),
    }
    xml = template.read_text()
    for key, value in values.items():
        xml = xml.replace("{" + key + "}", value)
    return xml


@functools.lru_cache(maxsize=8)
def _compiled_xml_model(xml: str) -> mujoco.MjModel:
    model = mujoco.MjModel.from_xml_string(xml)
    arm = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"panda0_link{i}") for i in range(8)]
    model.body_gravcomp[arm] = 1.0  # so that mj_step (if a user calls it) holds the arm up
    model.mat_reflectance[:] = 0.0  # reflections cost ~8x frame rate and add nothing here
    return model


def build_model(task: RobotTask, offwidth: int = 640, offheight: int = 480) -> mujoco.MjModel:
    """The compiled scene. Cached per process: envs never modify their model."""
    return _compiled_xml_model(scene_xml(task, offwidth, offheight))


class PandaIK:
    """Kinematic control of the Panda's end effector: damped-least-squares IK on the arm joints.

    The position task has priority. Two secondary terms act in its null space: "gripper
    down" (the orientation of ``Q_HOME``) and a pull towards a reference posture (the IK seed
    table's configuration nearest the target), which keeps the arm on one continuous IK branch
    away from its joint limits. If an update still misses the target (the arm folded into a
    joint limit), the IK restarts from the reference posture. Joint limits are respected.
    Positions here are in the task frame.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        seeds: np.ndarray | None = None,
        low: np.ndarray | None = None,
        high: np.ndarray | None = None,
    ) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, EE_SITE)
        self.q = self.data.qpos[:N_ARM]  # a view: writing it moves the arm
        self.lo = model.jnt_range[:N_ARM, 0].copy()
        self.hi = model.jnt_range[:N_ARM, 1].copy()
        self.lift = np.array([0.0, 0.0, TABLE_TOP])
        self._jp = np.zeros((3, model.nv))
        self._jr = np.zeros((3, model.nv))
        self._y = np.zeros(3)
        self._damp = IK_DAMPING**2 * np.eye(3)
        self.seeds = seeds
        if seeds is not None:
            self._seed_low = np.asarray(low, dtype=np.float64)
            self._seed_step = (np.asarray(high) - self._seed_low) / (np.array(seeds.shape[:3]) - 1)
            self._seed_max = np.array(seeds.shape[:3]) - 1
        self.data.qpos[N_ARM:] = FINGER_OPEN
        self.set_q(Q_HOME)
        # The rotation error to "gripper as in Q_HOME" is linear in the site's xmat (9,):
        # e = ½ (z × z_d + x × x_d) = −½ ([z_d]× z + [x_d]× x).
        rd = self.data.site_xmat[self.site].reshape(3, 3).copy()
        self._orient = np.zeros((3, 9))
        self._orient[:, 2::3] = -0.5 * _skew(rd[:, 2])  # columns of xmat: z is entries 2, 5, 8
        self._orient[:, 0::3] = -0.5 * _skew(rd[:, 0])

    def set_q(self, q: np.ndarray) -> None:
        self.q[:] = q
        mujoco.mj_kinematics(self.model, self.data)

    @property
    def ee(self) -> np.ndarray:
        """The end-effector position in the task frame (a copy)."""
        return self.data.site_xpos[self.site] - self.lift

    def tilt_deg(self) -> float:
        """Angle between the gripper axis and straight down, degrees."""
        z = self.data.site_xmat[self.site][8]
        return float(np.degrees(np.arccos(np.clip(-z, -1.0, 1.0))))

    def reference(self, target: np.ndarray) -> np.ndarray | None:
        """The seed table's configuration nearest ``target`` (task frame), if there is a table."""
        if self.seeds is None:
            return None
        idx = np.rint((target - self._seed_low) / self._seed_step).astype(int)
        np.minimum(np.maximum(idx, 0), self._seed_max, out=idx)
        q = self.seeds[idx[0], idx[1], idx[2]]
        return None if np.isnan(q[0]) else q

    def solve(self, target: np.ndarray, iters: int = IK_ITERS, tol: float = IK_TOL) -> float:
        """Move the arm so that the end effector reaches ``target`` (task frame).

        Returns the remaining position error (m).
        """
        world = target + self.lift
        ref = self.reference(target)
        err = self._solve(world, iters, tol, ref)
        if err > IK_RECOVER * tol and ref is not None:
            q_prev = self.q.copy()
            self.set_q(ref)
            err_ref = self._solve(world, 8 * iters, tol, ref)
            if err_ref < err:
                err = err_ref
            else:
                self.set_q(q_prev)
        return err

    def _solve(
        self,
        target: np.ndarray,
        iters: int,
        tol: float,
        ref: np.ndarray | None,
        orient_gain: float = IK_ORIENT_GAIN,
    ) -> float:
        """``iters`` IK iterations towards ``target`` (world frame); returns the error."""
        m, d, q = self.model, self.data, self.q
        x = d.site_xpos[self.site]
        xmat = d.site_xmat[self.site]
        jp, jr = self._jp[:, :N_ARM], self._jr[:, :N_ARM]
        for _ in range(iters):
            ep = target - x
            if ep @ ep < tol * tol:
                break
            mujoco.mj_comPos(m, d)
            mujoco.mj_jacSite(m, d, self._jp, self._jr, self.site)
            # Secondary motion s, projected into the position task's null space:
            # dq = J⁺ e + (I − J⁺J) s = s + Jᵀ (J Jᵀ + λ²I)⁻¹ (e − J s).
            s = orient_gain * (jr.T @ (self._orient @ xmat))
            if ref is not None:
                s += IK_POSTURE_GAIN * (ref - q)
            q_new = q + self._step(jp, s, ep)
            blocked = (q_new < self.lo) | (q_new > self.hi)
            if blocked.any():  # joints at a limit drop out; the others take over their share
                free = ~blocked
                s *= free
                q_new = q + self._step(jp * free, s, ep)
            np.minimum(np.maximum(q_new, self.lo), self.hi, out=q)
            mujoco.mj_kinematics(m, d)
        ep = target - x
        return float(np.sqrt(ep @ ep))

    def _step(self, jp: np.ndarray, s: np.ndarray, ep: np.ndarray) -> np.ndarray:
        """dq = s + Jᵀ (J Jᵀ + λ²I)⁻¹ (e − J s), via MuJoCo's Cholesky (no numpy.linalg cost)."""
        a = jp @ jp.T
        a += self._damp
        mujoco.mju_cholFactor(a, 0.0)
        mujoco.mju_cholSolve(self._y, a, ep - jp @ s)
        return s + jp.T @ self._y


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


# ---------------------------------------------------------------------------------- IK seeds
def _grid(task: RobotTask, shape: tuple[int, int, int] = SEED_GRID) -> np.ndarray:
    axes = [np.linspace(task.workspace_low[k], task.workspace_high[k], shape[k]) for k in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)


def build_seed_table(task: RobotTask, shape: tuple[int, int, int] = SEED_GRID) -> np.ndarray:
    """Joint configurations reaching a grid over the workspace box, shape (*shape, 7).

    A flood fill from the home pose: each node is solved starting from a solved neighbour, so
    neighbouring nodes lie on one continuous IK branch; failed nodes are retried from their
    other neighbours. Used to start the IK at reset (any start in the box is near a node).
    Takes a few seconds; the default task's table ships in strol_gym/assets.
    """
    ik = PandaIK(build_model(task))
    pts = _grid(task, shape)
    table = np.full((*shape, N_ARM), np.nan)
    err = np.full(shape, np.inf)
    ik.set_q(Q_HOME)
    start = np.unravel_index(np.argmin(np.linalg.norm(pts - ik.ee, axis=-1)), shape)

    def neighbours(idx: tuple[int, ...]):
        for ax in range(3):
            for s in (-1, 1):
                j = list(idx)
                j[ax] += s
                if 0 <= j[ax] < shape[ax]:
                    yield tuple(j)

    def attempt(idx: tuple[int, ...], q0: np.ndarray) -> None:
        ik.set_q(q0)
        e = ik.solve(pts[idx], iters=60, tol=1e-5)
        if e > 1e-4:  # the gripper-down term may block the position: solve for it alone
            ik.set_q(q0)
            e = ik._solve(pts[idx] + ik.lift, 240, 1e-5, None, orient_gain=0.0)
        if e < err[idx]:
            table[idx], err[idx] = ik.q.copy(), e

    frontier, seen = [(start, Q_HOME)], {start}
    while frontier:
        nxt = []
        for idx, q0 in frontier:
            attempt(idx, q0)
            for j in neighbours(idx):
                if j not in seen:
                    seen.add(j)
                    nxt.append((j, table[idx]))
        frontier = nxt
    for _ in range(3):
        for idx in zip(*np.nonzero(err > 1e-3), strict=True):
            for j in neighbours(idx):
                if err[j] < 1e-3:
                    attempt(idx, table[j])
    return table


def _seed_table_path() -> Path:
    return Path(str(importlib.resources.files("strol_gym").joinpath("assets/robot_ik_seeds.npz")))


def save_seed_table(task: RobotTask | None = None, path: Path | None = None) -> Path:
    """Regenerate the shipped IK seed table (``python -m strol_gym.envs.robot``)."""
    task = task or RobotTask()
    path = path or _seed_table_path()
    table = build_seed_table(task)
    np.savez_compressed(
        path, q=table, low=task.workspace_low, high=task.workspace_high, base=BASE_IN_TASK
    )
    return path


@functools.lru_cache(maxsize=8)
def _seed_table_cached(low: tuple, high: tuple) -> np.ndarray:
    path = _seed_table_path()
    if path.exists():
        with np.load(path) as f:
            if (
                np.allclose(f["low"], low)
                and np.allclose(f["high"], high)
                and np.allclose(f["base"], BASE_IN_TASK)
            ):
                return f["q"]
    task = RobotTask(workspace_low=np.array(low), workspace_high=np.array(high))
    return build_seed_table(task)


def seed_table(task: RobotTask) -> np.ndarray:
    """The IK seed table for ``task``'s box: shipped for the default box, else built once."""
    return _seed_table_cached(tuple(task.workspace_low), tuple(task.workspace_high))


# ---------------------------------------------------------------------------------- the env
class RobotEnv(CorrectionEnvMixin, gym.Env):
    """StROL-Robot-v0: a Franka Panda whose end effector a human corrects toward a plate or cup.

    ## Description

    The paper's **Robot** setting (StROL, RA-L 2024, "Simulations") on a real 7-DoF Franka
    Panda in MuJoCo (gymnasium-robotics' shipped model files). The arm stands on a table with
    a plate and a cup. The Task state x is the end-effector position (site ``end_effector``)
    in the task frame: metres, x forward from the robot base, y to the left, z up from the
    table top. Features φ(x) = (−‖x_xy − plate_xy‖, −‖x − cup‖) (``RobotTask``). The human
    wants θ*: positive weights mean "go near", negative "stay away". During the first
    ``n_corrections`` steps the human corrects: its action u_H is an end-effector
    displacement that moves the arm together with the robot's own action u_R. An online
    learner (``strol_gym.wrappers``) updates the robot's estimate θ̂ from these corrections.

    Each step the end effector's target is the Task's transition
    f(x, u_H, u_R) = clip(x + u_R + u_H, workspace box), and damped-least-squares IK (a few
    iterations of ``mj_kinematics`` / ``mj_jacSite``) moves the arm there. The arm is
    positioned kinematically: the IK solution is written to ``qpos`` (no dynamics integration,
    which keeps the env fast and exactly on target); the actuators' ``ctrl`` is kept equal to
    it and the arm bodies have gravity compensation, so ``mj_step`` holds the pose if you call
    it yourself. The position task has priority over "gripper pointing down", which holds in
    most of the box; the gripper tilts near a few edges. The observed state is the real
    end-effector position read back from MuJoCo (usually within ``IK_TOL`` = 0.2 mm of the
    target, within 1 mm in our tests; ``info["ik_error"]`` reports it).

    Workspace box: [0.15, 0.75] x [−0.55, 0.35] x [0, 0.7] m (the authors' point robot used
    [0, 0.8] x [−0.6, 0.4] x [0, 0.7], which a Panda cannot reach; see docs/fidelity.md). The
    Panda's base sits at (0.05, −0.10, 0.10) in the task frame, on a 10 cm pedestal.

    ## Action Space

    ``Box(-1, 1, (3,), float32)``: the robot's end-effector velocity, scaled by
    ``task.robot_action_bound`` (0.1 m per step and axis) to the displacement u_R. Out-of-range
    actions are clipped to [−1, 1]; a NaN or infinite action raises ``ValueError``.

    ## Observation Space

    ``Dict`` of float32 Boxes (the space never changes):

    - ``"state"`` (3,): exactly the Task state x, the end effector's position (m, task frame).
    - ``"correction"`` (3,): u_H, the human's displacement this step (m, noise and bias
      included); zeros when the human does not correct (and after reset).
    - ``"theta_hat"`` (2,): the robot's current estimate θ̂ (see ``set_theta_hat``).
    - ``"phi"`` (2,): φ(x), the features of the state.

    ## Rewards

    R(x', θ*) = θ*·φ(x'), the human's reward of the state reached. ``info`` carries
    ``"features"`` (name -> value), ``"phi"``, ``"correction"`` (u_H), ``"robot_action"`` (u_R as
    applied, m), ``"theta_star"`` (for evaluation only), ``"theta_hat"``, ``"is_correction"``,
    ``"target"`` (the IK target f(x, u_H, u_R)) and ``"ik_error"`` (m).

    ## Starting State

    Drawn from ``env.np_random`` at reset, in this order: θ* from the prior, then the start
    x0 uniformly in the workspace box (``task.sample_start``); the human is built with
    ``rng=env.np_random``, so its candidate actions and noise continue the same stream. Two
    envs reset with the same seed see the same θ*, start and human draws (paired runs).
    θ̂ starts at the mean of the bimodal prior's modes, (0, 0), unless ``set_theta_hat`` is
    called. ``reset(options={"theta_star": ..., "state": ...})`` overrides either draw (the
    draws still happen, so pairing is kept).

    ## Episode End

    Never terminates. Truncated after 10 steps: ``gymnasium.make`` wraps the env in a
    ``TimeLimit`` (``gymnasium.make("StROL-Robot-v0", max_episode_steps=N)`` changes it). An
    env constructed directly truncates only if given ``max_episode_steps``.

    ## Arguments

    - ``sigma`` (float ≥ 0, default 0): noise, δ ~ N(ε a_max, (σ a_max)²) per axis, a_max = 0.1 m.
    - ``bias`` (finite float, default 0): ε, as a fraction of a_max.
    - ``prior`` ("bimodal" | "uniform" | a ``Prior`` | array of modes, default "bimodal"): P(θ*).
      "bimodal": modes (0.8, −0.8) (reach the plate, avoid the cup) and (−0.8, 0.8), with
      N(0, 0.1²) jitter; "uniform": [−1, 1]².
    - ``human`` ("nominal" | "boltzmann" | "driver" | callable ``(task, theta_star, rng) ->
      Human``, default "nominal" = the eq. M6 teacher ``strol_gym.humans.NominalHuman``).
    - ``beta`` (float ≥ 0, default 50): rationality of the "boltzmann" human.
    - ``n_corrections`` (int ≥ 0, default 5): steps during which the human corrects.
    - ``max_episode_steps`` (int ≥ 1 or None): through ``gymnasium.make`` this is gymnasium's
      own TimeLimit argument (registered default 10); given to ``RobotEnv`` directly, the env
      truncates itself after that many steps (default None: never).
    - ``render_mode`` (None | "human" | "rgb_array"); ``width``, ``height`` (int in
      [16, 4096], default 480 x 360). Headless "rgb_array" uses ``MUJOCO_GL=egl`` (set when
      this module imports MuJoCo first and there is no display) or osmesa; "human" needs a
      display.
    - ``task`` (``RobotTask`` or None): a variant of the setting (its prior is replaced by
      ``prior``). A workspace box other than the default builds its IK seed table once (~5 s).

    ## Version History

    - v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 5}

    def __init__(
        self,
        sigma: float = 0.0,
        bias: float = 0.0,
        prior: str | Prior | Any = "bimodal",
        human: str | HumanFactory = "nominal",
        beta: float = 50.0,
        n_corrections: int = 5,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        task: RobotTask | None = None,
        **unknown: Any,
    ) -> None:
        self._configure(
            "StROL-Robot-v0",
            task,
            RobotTask,
            unknown,
            sigma=sigma,
            bias=bias,
            prior=prior,
            human=human,
            beta=beta,
            n_corrections=n_corrections,
            render_mode=render_mode,
        )
        self.task: RobotTask
        if max_episode_steps is not None:
            max_episode_steps = int_arg("max_episode_steps", max_episode_steps, 1)
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.width = int_arg("width", width, 16, 4096)
        self.height = int_arg("height", height, 16, 4096)

        t = self.task
        d, s, a = t.dim, t.state_dim, t.action_dim
        margin = 0.1
        f32 = np.float32
        self.observation_space = spaces.Dict(
            {
                "state": spaces.Box(
                    (t.workspace_low - margin).astype(f32),
                    (t.workspace_high + margin).astype(f32),
                    dtype=f32,
                ),
                "correction": spaces.Box(-np.inf, np.inf, shape=(a,), dtype=f32),
                "theta_hat": spaces.Box(-np.inf, np.inf, shape=(d,), dtype=f32),
                "phi": spaces.Box(-np.inf, 0.0, shape=(d,), dtype=f32),
            }
        )
        self.action_space = spaces.Box(-1.0, 1.0, shape=(a,), dtype=f32)
        self._zeros = np.zeros(a)
        self.theta_star = t.prior.mean.copy()
        self.human: Human | None = None
        self.steps = 0
        self._x = np.zeros(s)
        self._renderer: mujoco.Renderer | None = None
        self._viewer: Any = None
        self._build()
        self._x = self._ik.ee

    # ------------------------------------------------------------------ model, θ̂
    def _build(self, qpos: np.ndarray | None = None) -> None:
        off_w, off_h = max(640, self.width), max(480, self.height)
        self.model = build_model(self.task, off_w, off_h)
        seeds = seed_table(self.task)
        self._ik = PandaIK(self.model, seeds, self.task.workspace_low, self.task.workspace_high)
        self.data = self._ik.data
        if qpos is not None:
            self.data.qpos[:] = qpos
            mujoco.mj_kinematics(self.model, self.data)
        self.data.ctrl[:N_ARM] = self._ik.q

    def move_to(self, x: np.ndarray) -> np.ndarray:
        """Put the end effector at ``x`` (task frame) from the nearest IK seed; returns the real
        position reached."""
        x = np.asarray(x, dtype=np.float64)
        q0 = self._ik.reference(x)
        self._ik.set_q(Q_HOME if q0 is None else q0)
        self._ik.solve(x, iters=2 * IK_ITERS)
        self.data.ctrl[:N_ARM] = self._ik.q
        return self._ik.ee

    # ------------------------------------------------------------------ reset / step
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        super().reset(seed=seed)
        theta_override, x_override = self._reset_overrides(options)
        rng = self.np_random
        theta_star = self.task.prior.sample(rng, 1)[0]
        x0 = self.task.sample_start(rng, 1)[0]
        if theta_override is not None:
            theta_star = theta_override
        if x_override is not None:
            x0 = np.clip(x_override, self.task.workspace_low, self.task.workspace_high)
        self.theta_star = theta_star
        self.theta_hat = self._default_theta_hat()
        self.human = self._make_human(theta_star, rng)
        self.steps = 0
        self._x = self.move_to(x0)
        phi = self.task.features(self._x)
        obs = self._obs(self._zeros, phi)
        info = self._make_info(phi, self._zeros, self._zeros, False, self._x, 0.0)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        u_r = self._robot_action(action)
        if self.human is None:
            raise RuntimeError("call reset() before step()")
        is_correction = self.steps < self.n_corrections
        if is_correction:
            u_h = np.asarray(self.human.act(self._x, u_r, self.theta_hat), dtype=np.float64)
            if u_h.shape != (3,) or not np.isfinite(u_h).all():
                raise ValueError(f"the human's correction must be 3 finite numbers, got {u_h}")
        else:
            u_h = self._zeros
        target = self.task.dynamics(self._x, u_h, u_r)
        ik_error = self._ik.solve(target)
        self.data.ctrl[:N_ARM] = self._ik.q
        self.steps += 1
        self._x = self._ik.ee
        phi = self.task.features(self._x)
        reward = float(phi @ self.theta_star)
        truncated = self.max_episode_steps is not None and self.steps >= self.max_episode_steps
        obs = self._obs(u_h, phi)
        info = self._make_info(phi, u_h, u_r, is_correction, target, ik_error)
        if self.render_mode == "human":
            self.render()
        return obs, reward, False, truncated, info

    def _obs(self, u_h: np.ndarray, phi: np.ndarray) -> dict[str, np.ndarray]:
        return {
            "state": self._x.astype(np.float32),
            "correction": u_h.astype(np.float32),
            "theta_hat": self.theta_hat.astype(np.float32),
            "phi": phi.astype(np.float32),
        }

    def _make_info(
        self,
        phi: np.ndarray,
        u_h: np.ndarray,
        u_r: np.ndarray,
        is_correction: bool,
        target: np.ndarray,
        ik_error: float,
    ) -> dict[str, Any]:
        info = self._info(phi, u_h, u_r, is_correction)
        info["target"] = target
        info["ik_error"] = ik_error
        return info

    # ------------------------------------------------------------------ render, close, pickle
    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; "
                'make the env with render_mode="rgb_array" or "human"'
            )
            return None
        mujoco.mj_forward(self.model, self.data)
        if self.render_mode == "rgb_array":
            if self._renderer is None:
                self._renderer = mujoco.Renderer(self.model, self.height, self.width)
                flags = self._renderer.scene.flags
                flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
                flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
            self._renderer.update_scene(self.data, camera="overview")
            return self._renderer.render()
        if self._viewer is None:
            if os.name == "posix" and not (
                os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
            ):
                # GLFW would abort the whole process; fail politely instead.
                raise RuntimeError(
                    'render_mode="human" needs a display (DISPLAY is not set); '
                    'use render_mode="rgb_array" for headless rendering'
                )
            from mujoco import viewer

            self._viewer = viewer.launch_passive(self.model, self.data)
        self._viewer.sync()
        return None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        super().close()

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        for key in ("model", "data", "_ik", "_renderer", "_viewer"):
            state.pop(key, None)
        state["_qpos"] = self.data.qpos.copy()
        return state

    def __setstate__(self, state: dict) -> None:
        qpos = state.pop("_qpos")
        self.__dict__.update(state)
        self._renderer = None
        self._viewer = None
        self._build(qpos)


if __name__ == "__main__":
    print(f"wrote {save_seed_table()}")
