"""The IK seed table of the Robot env: joint configurations reaching a grid over the workspace.

The default task's table ships in ``strol_gym/assets/robot_ik_seeds.npz``; regenerate it with
``python -m strol_gym.envs.robot.seeds``. Another workspace box builds its table once (~5 s).
"""

from __future__ import annotations

import functools
import importlib.resources
from pathlib import Path

import numpy as np

from strol_gym.envs.panda.ik import PandaIK
from strol_gym.envs.panda.model import N_ARM, Q_HOME
from strol_gym.envs.robot.scene import BASE_IN_TASK, TABLE_TOP, build_model
from strol_gym.tasks.robot import RobotTask

SEED_GRID = (9, 11, 8)
"""IK seed table resolution over the workspace box (x, y, z)."""


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
    ik = PandaIK(build_model(task), lift=TABLE_TOP)
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
    """Regenerate the shipped IK seed table (``python -m strol_gym.envs.robot.seeds``)."""
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


if __name__ == "__main__":
    print(f"wrote {save_seed_table()}")
