"""Pose helpers of the study: differences of poses (angles wrapped), rotation vectors, straight
paths between poses, and the box of poses the arm reaches (``within_reach``, v1's planning box)."""

from __future__ import annotations

import math

import numpy as np

from strol_gym.tasks.study import PITCHER, StudyTask, wrap_angle

REACH_LOW = np.array([0.25, -0.45, 0.20])
REACH_HIGH = np.array([0.70, 0.55, 0.60])
"""The planning box the robot executes within (m): the cup stays where the arm reaches it with
the wrist free, its bottom (10 cm below the rim) clear of the plate's riser (docs/study.md
measures it; the pitcher has its own keep-out zone, ``PITCHER_CLEAR``)."""
REACH_ANGLE = 1.0
"""|roll|, |pitch| the executed plan may reach (rad): beyond it the wrist binds far from home."""
SHOULDER = np.array([0.0, 0.0, 0.333])
REACH_RADIUS = 0.70
"""m from the shoulder (joint 2's axis) the cup may go: the stretched elbow (joint 4 at its
limit) leaves the cup short of setpoints beyond about 0.75 m."""
PITCHER_CLEAR = (0.14, 0.37)
"""The pitcher's keep-out zone for the cup (m): within 0.14 m of its axis (its 7 cm radius, the
cup's 4 cm and 3 cm to spare) the cup's rim stays above 0.37 m (the pitcher's 24 cm, the cup's
10 cm below its rim and 3 cm to spare)."""


def angle_delta(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a − b for poses: positions subtract, angles wrap to [−π, π)."""
    d = np.asarray(a, dtype=np.float64) - b
    if d.shape[-1] > 3:
        d[..., 3:] = wrap_angle(d[..., 3:])
    return d


def rotation_error(r_target: np.ndarray, r_now: np.ndarray) -> np.ndarray:
    """The rotation vector (world frame, rad) taking ``r_now`` to ``r_target`` (3x3 matrices).

    Plain floats after the one product (``dot``: half the call cost of ``@``): the env calls it
    every step (setpoint velocity) and the user every step of a push, and numpy's per-call cost
    dominates on 3x3 matrices.
    """
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = r_target.dot(r_now.T).tolist()
    angle = math.acos(min(1.0, max(-1.0, 0.5 * (r00 + r11 + r22 - 1.0))))
    ax, ay, az = r21 - r12, r02 - r20, r10 - r01
    s = math.sqrt(ax * ax + ay * ay + az * az)
    if s < 1e-9:
        return np.zeros(3)
    return np.array((ax / s * angle, ay / s * angle, az / s * angle))


def straight(a: np.ndarray, b: np.ndarray, bound: float) -> np.ndarray:
    """Waypoints from pose a to pose b, at most ``bound`` apart per axis (angles: 2 bound)."""
    delta = angle_delta(b, a)
    scale = np.array([1.0] * 3 + [2.0] * (len(a) - 3))
    n = max(1, int(np.ceil(np.max(np.abs(delta) / (bound * scale)))))
    return a + np.linspace(0.0, 1.0, n + 1)[:, None] * delta


def within_reach(
    task: StudyTask, plan: np.ndarray, low: np.ndarray, high: np.ndarray, angle: float
) -> np.ndarray:
    """``plan`` (T+1, s) with every waypoint after the first moved into the box (positions in
    [low, high], within ``REACH_RADIUS`` of the shoulder and out of the pitcher's keep-out zone
    (``PITCHER_CLEAR``: lifted over it), |roll|, |pitch| ≤ ``angle``; yaw as planned), each
    step still within the planner's bounds (``plan_pos_bound``, ``plan_ang_bound`` per axis):
    a start outside the box (where a person left the cup) is left at the planner's pace, not in
    one jump.

    The Task's planning box lets θ̂ ask for poses the arm cannot reach, or that put the cup into
    the table, the plate or the pitcher: there the cup stops centimetres short of its setpoint
    and drifts while the arm settles at its boundary. The regret is still the Task's (its
    planner, its box): this box is what the robot executes."""
    plan = np.asarray(plan, dtype=np.float64)
    lo, hi = low.tolist(), high.tolist()
    step = [task.plan_pos_bound] * 3
    if task.oriented:
        lo, hi = [*lo, -angle, -angle, -math.inf], [*hi, angle, angle, math.inf]
        step += [task.plan_ang_bound] * 3
    lo_a, hi_a, step_a = np.array(lo), np.array(hi), np.array(step)
    out = plan.copy()
    for i in range(1, len(plan)):
        goal = np.clip(plan[i], lo_a, hi_a)
        arm = goal[:3] - SHOULDER
        far = float(np.linalg.norm(arm))
        if far > REACH_RADIUS:
            goal[:3] = SHOULDER + arm * (REACH_RADIUS / far)
        if _over_pitcher(goal):
            goal[2] = PITCHER_CLEAR[1]  # above it, where the xy distance is the same
        move = angle_delta(goal, out[i - 1])
        out[i] = out[i - 1] + np.clip(move, -step_a, step_a)
        if _over_pitcher(out[i]):  # rise first, then move in over it
            out[i, :2] = out[i - 1, :2]
    return out


def _over_pitcher(x: np.ndarray) -> bool:
    """Whether the cup at ``x`` would be in the pitcher's keep-out zone (``PITCHER_CLEAR``)."""
    near = math.hypot(x[0] - PITCHER[0], x[1] - PITCHER[1]) < PITCHER_CLEAR[0]
    return near and x[2] < PITCHER_CLEAR[1]
