"""The reachable set StROL-Study-v2's Tasks carry (``strol_gym.tasks.study``: ``REACH_*``,
``WRIST_LEVER``), computed offline from the arm model.

    .venv/bin/python benchmarks/speed/study_reach.py [--samples 400] [--seed 0]

Cup poses are drawn uniformly over the Tasks' planning box (positions; Tasks 2-3 also roll and
pitch in [−1.2, 1.2] at the home yaw; Task 1's cup upright, as its controller holds it), and
each is solved by damped-least-squares IK on the scene's Panda from the home joints, every
joint kept 0.05 rad inside its limits. A pose is reachable if the IK ends within 0.5 mm and
0.002 rad. Printed: the share reachable inside candidate sets (the hand within R of the
shoulder, |roll|, |pitch| ≤ a, the shipped box), the shipped set's first; and θ*'s plan's
return per Task with the hulls alone and with the hulls and the reachable set. The Task itself
keeps only the numbers (it knows no simulator).
"""

from __future__ import annotations

import argparse
import dataclasses

import mujoco
import numpy as np

from strol_gym.envs.study.scene import build_model, model_q
from strol_gym.tasks.study import (
    REACH_ANGLE,
    REACH_HIGH,
    REACH_LOW,
    REACH_RADIUS,
    REACH_SHOULDER,
    STUDY_TASKS_V2,
    WRIST_LEVER,
    rpy_to_mat,
)


def solve(m, d, site, q0, pos, rot, lo, hi, iters: int = 150) -> bool:
    """Damped-least-squares IK for the cup site's pose; True if it converged."""
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    d.qpos[:7] = q0
    for _ in range(iters):
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        now = d.site_xmat[site].reshape(3, 3)
        err_r = rot @ now.T
        e = np.concatenate(
            [
                pos - d.site_xpos[site],
                0.5
                * np.array(
                    [
                        err_r[2, 1] - err_r[1, 2],
                        err_r[0, 2] - err_r[2, 0],
                        err_r[1, 0] - err_r[0, 1],
                    ]
                ),
            ]
        )
        if np.linalg.norm(e[:3]) < 5e-4 and np.linalg.norm(e[3:]) < 2e-3:
            return True
        mujoco.mj_jacSite(m, d, jp, jr, site)
        jac = np.vstack([jp[:, :7], jr[:, :7]])
        step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), e)
        d.qpos[:7] = np.clip(d.qpos[:7] + step, lo, hi)
    return False


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    m = build_model()
    d = mujoco.MjData(m)
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "cup")
    lo, hi = m.jnt_range[:7, 0] + 0.05, m.jnt_range[:7, 1] - 0.05
    for number in (1, 2):
        task = STUDY_TASKS_V2[number]()
        rng = np.random.default_rng([args.seed, number])
        q0 = model_q(task.home_q)
        d.qpos[:7] = q0
        mujoco.mj_forward(m, d)
        home_rot = d.site_xmat[site].reshape(3, 3).copy()
        pos = rng.uniform([0.15, -0.6, 0.05], [0.8, 0.65, 0.7], (args.samples, 3))
        ang = rng.uniform(-1.2, 1.2, (args.samples, 2))
        if number == 1:
            rots = np.broadcast_to(home_rot, (args.samples, 3, 3))
        else:
            rots = rpy_to_mat(np.column_stack([ang, np.full(args.samples, task.start[5])]))
        ok = np.array([solve(m, d, site, q0, p, r, lo, hi) for p, r in zip(pos, rots, strict=True)])
        hand = pos + WRIST_LEVER * rots[:, :, 2]
        far = np.linalg.norm(hand - REACH_SHOULDER, axis=1)
        in_box = ((pos >= REACH_LOW) & (pos <= REACH_HIGH)).all(1)
        print(f"Task {number} ({'upright cup' if number == 1 else 'roll, pitch drawn'}):")
        for radius in (REACH_RADIUS, 0.70, 0.80, 0.85):
            for angle in (REACH_ANGLE, 0.6, 1.0) if number > 1 else (REACH_ANGLE,):
                inside = in_box & (far <= radius)
                if number > 1:
                    inside &= (np.abs(ang) <= angle).all(1)
                tag = " (shipped)" if (radius, angle) == (REACH_RADIUS, REACH_ANGLE) else ""
                print(
                    f"  hand within {radius:.2f} m, |roll|,|pitch| <= {angle:.1f}{tag}: "
                    f"{inside.sum()} samples, {ok[inside].mean():.1%} reachable"
                )
    for number in (1, 2, 3):
        task = STUDY_TASKS_V2[number]()
        free = dataclasses.replace(
            task,
            reach_radius=10.0,
            reach_low=np.array([0.2, -0.6, task.floor]),
            reach_high=np.array([0.8, 0.6, 0.7]),
            reach_angle=1.3,
        )
        theta = task.theta_star
        ret = [(t.features(t.plan(theta, t.start)[0][1:]) @ theta).sum() for t in (free, task)]
        print(
            f"Task {number}: θ*'s plan's return, hulls only {ret[0]:.3f}, hulls and reachable "
            f"set {ret[1]:.3f}"
        )


if __name__ == "__main__":
    main()
