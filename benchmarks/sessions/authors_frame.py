"""The authors' logged hand poses in the Study Tasks' cup frame, derived from kinematics facts.

Their logs hold 6-D poses (x, y, z, roll′, pitch, yaw) of their hand frame: the Panda's
forward kinematics (Franka's published modified-DH table) to link 7, then a −π/4 turn about its
z axis with a 0.2105 m offset along it, with roll′ = roll ± π; a shift of the roll by π is
exactly a right-multiplication of the rotation by Rx(π), so a logged pose is the frame
``F_log = (p, R_hand · Rx(π))``, roll, pitch, yaw read as R = Rz(yaw) Ry(pitch) Rx(roll).

Our cup frame is a fixed transform of that frame (both are rigid on link 7). It is not typed
in here: :func:`fit_transform` measures it at the two home joint vectors, as F_log(home)⁻¹ ·
F_cup(home), with F_cup read from the Study env's MuJoCo model (site ``cup``), averages the two,
and reports how well the average predicts each home (the residual). A pose then maps by
``F_cup = F_log · T``.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from strol_gym.envs.study.env import StudyEnv
from strol_gym.envs.study.versions import V0
from strol_gym.tasks.study import STUDY_TASKS, mat_to_rpy, rpy_to_mat, wrap_angle

# Franka Panda modified-DH parameters (a, d, alpha) per joint, metres and radians (datasheet).
_DH = (
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -math.pi / 2),
    (0.0, 0.316, math.pi / 2),
    (0.0825, 0.0, math.pi / 2),
    (-0.0825, 0.384, -math.pi / 2),
    (0.0, 0.0, math.pi / 2),
    (0.088, 0.0, math.pi / 2),
)
HAND_OFFSET = 0.2105
"""The authors' hand frame: this far along link 7's z axis (m) ..."""
HAND_TURN = -math.pi / 4
"""... turned this much about it (rad)."""
_RX_PI = np.diag([1.0, -1.0, -1.0])


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _homogeneous(rot: np.ndarray, pos: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, pos
    return out


def hand_frame(q: np.ndarray) -> np.ndarray:
    """The authors' hand frame (4 × 4, base frame) at joints ``q`` (real Panda convention)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape != (7,) or not np.isfinite(q).all():
        raise ValueError(f"q must be 7 finite joint angles (rad), got shape {q.shape}")
    out = np.eye(4)
    for (a, d, alpha), qi in zip(_DH, q.tolist(), strict=True):
        link = _homogeneous(_rot_x(alpha), np.array([a, 0.0, 0.0]))
        out = out @ link @ _homogeneous(_rot_z(qi), np.array([0.0, 0.0, d]))
    return out @ _homogeneous(_rot_z(HAND_TURN), np.array([0.0, 0.0, HAND_OFFSET]))


def logged_frame(q: np.ndarray) -> np.ndarray:
    """The frame the authors' logged pose describes at ``q``: the hand frame × Rx(π)."""
    out = hand_frame(q)
    out[:3, :3] = out[:3, :3] @ _RX_PI
    return out


def pose_to_frame(pose: np.ndarray) -> np.ndarray:
    """(..., 6) poses (x, y, z, roll, pitch, yaw) -> (..., 4, 4) frames."""
    pose = np.asarray(pose, dtype=np.float64)
    out = np.zeros((*pose.shape[:-1], 4, 4))
    out[..., :3, :3] = rpy_to_mat(pose[..., 3:6])
    out[..., :3, 3] = pose[..., :3]
    out[..., 3, 3] = 1.0
    return out


def frame_to_pose(frame: np.ndarray) -> np.ndarray:
    """(..., 4, 4) frames -> (..., 6) poses."""
    frame = np.asarray(frame, dtype=np.float64)
    return np.concatenate([frame[..., :3, 3], mat_to_rpy(frame[..., :3, :3])], axis=-1)


def _nearest_rotation(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return r


def rotation_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angle (rad) of the rotation from ``a`` to ``b``, (..., 3, 3) each."""
    tr = np.einsum("...ij,...ij->...", a, b)
    return np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))


@dataclasses.dataclass(frozen=True)
class FrameFit:
    """The fitted cup-in-logged-frame transform and how well it predicts each home."""

    transform: np.ndarray
    """4 × 4: F_cup = F_log · transform."""
    residual_mm: dict[int, float]
    """Per home (keyed by the Task whose home it is: 1, 2): position error of the fit (mm)."""
    residual_deg: dict[int, float]
    """Per home: rotation error of the fit (degrees)."""
    loo_mm: dict[int, float]
    """Per home: position error when fitted at the *other* home only (mm)."""

    @property
    def offset_mm(self) -> np.ndarray:
        """The cup's origin in the logged frame (mm)."""
        return self.transform[:3, 3] * 1000.0

    @property
    def turn_deg(self) -> float:
        """The turn about the logged frame's z axis (degrees), from the fitted rotation."""
        r = self.transform[:3, :3]
        return math.degrees(math.atan2(r[1, 0], r[0, 0]))

    def to_cup(self, pose: np.ndarray) -> np.ndarray:
        """Logged poses (..., 6) -> cup poses (..., 6) in the Study Tasks' frame."""
        return frame_to_pose(pose_to_frame(pose) @ self.transform)

    def to_logged(self, cup: np.ndarray) -> np.ndarray:
        """Cup poses (..., 6) -> the authors' logged poses (..., 6): ``to_cup``'s inverse."""
        out = frame_to_pose(pose_to_frame(cup) @ np.linalg.inv(self.transform))
        return np.concatenate([out[..., :3], wrap_angle(out[..., 3:])], axis=-1)


def cup_frames_at_homes() -> dict[int, np.ndarray]:
    """Our cup frame (4 × 4) at Task 1's and Task 2's home joints, from the Study env's model."""
    import warnings

    import gymnasium as gym
    import mujoco

    out = {}
    for number in (1, 2):
        with warnings.catch_warnings():  # v0 is the version whose Tasks the logs name
            warnings.simplefilter("ignore", DeprecationWarning)
            env = gym.make(V0.env_id, task=number)
        try:
            env.reset(seed=0)
            base = env.unwrapped
            assert isinstance(base, StudyEnv)  # StROL-Study-v0 is one
            site = mujoco.mj_name2id(base.model, mujoco.mjtObj.mjOBJ_SITE, "cup")
            rot = np.array(base.data.site_xmat[site]).reshape(3, 3)
            out[number] = _homogeneous(rot, np.array(base.data.site_xpos[site]))
        finally:
            env.close()
    return out


def _relative(number: int, cup: np.ndarray) -> np.ndarray:
    return np.linalg.inv(logged_frame(STUDY_TASKS[number]().home_q)) @ cup


def _errors(t: np.ndarray, number: int, cup: np.ndarray) -> tuple[float, float]:
    pred = logged_frame(STUDY_TASKS[number]().home_q) @ t
    mm = float(np.linalg.norm(pred[:3, 3] - cup[:3, 3]) * 1000.0)
    return mm, math.degrees(float(rotation_angle(pred[:3, :3], cup[:3, :3])))


@functools.lru_cache(maxsize=1)
def fit_transform() -> FrameFit:
    """Measure the logged-frame → cup-frame transform at both homes (see the module docstring)."""
    cups = cup_frames_at_homes()
    rel = {n: _relative(n, c) for n, c in cups.items()}
    t = np.eye(4)
    t[:3, :3] = _nearest_rotation(np.asarray(sum(r[:3, :3] for r in rel.values())))
    t[:3, 3] = np.mean([r[:3, 3] for r in rel.values()], axis=0)
    res = {n: _errors(t, n, c) for n, c in cups.items()}
    loo = {n: _errors(rel[3 - n], n, c)[0] for n, c in cups.items()}
    return FrameFit(
        t,
        {n: r[0] for n, r in res.items()},
        {n: r[1] for n, r in res.items()},
        loo,
    )


__all__ = [
    "FrameFit",
    "fit_transform",
    "frame_to_pose",
    "hand_frame",
    "logged_frame",
    "pose_to_frame",
    "rotation_angle",
]
