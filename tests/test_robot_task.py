"""RobotTask: features, their Jacobian, the transition, the workspace and the planner."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from strol_gym.planning import plan_linear_reward, straight_line_starts
from strol_gym.tasks.robot import ROBOT_MODES, RobotTask

TASK = RobotTask()


def test_features_by_hand():
    # plate (0.35, 0.10, 0.00), cup (0.70, −0.45, 0.10)
    x = np.array([0.35 + 0.3, 0.10 + 0.4, 1.0])  # planar 0.5 from the plate (z ignored)
    np.testing.assert_allclose(TASK.features(x)[0], -0.5)
    x = np.array([0.70 + 0.2, -0.45, 0.10 + 0.2])  # 0.2·√2 from the cup
    np.testing.assert_allclose(TASK.features(x)[1], -0.2 * np.sqrt(2))
    assert TASK.features(np.zeros((4, 5, 3))).shape == (4, 5, 2)
    np.testing.assert_allclose(TASK.reward(TASK.plate, np.array([1.0, 0.0])), 0.0)


def test_feature_jacobian_matches_finite_differences():
    x = np.random.default_rng(0).uniform(TASK.workspace_low, TASK.workspace_high, (20, 3))
    eps = 1e-6
    num = np.stack(
        [(TASK.features(x + eps * e) - TASK.features(x - eps * e)) / (2 * eps) for e in np.eye(3)],
        axis=-1,
    )
    np.testing.assert_allclose(TASK.feature_jacobian(x), num, atol=1e-7)


def test_dynamics_adds_and_clips_to_the_workspace():
    x = np.array([0.5, 0.0, 0.3])
    np.testing.assert_allclose(
        TASK.dynamics(x, np.array([0.1, 0, 0]), np.array([0, -0.05, 0])), [0.6, -0.05, 0.3]
    )
    far = TASK.dynamics(TASK.workspace_high, np.full(3, 0.1), np.full(3, 0.1))
    np.testing.assert_allclose(far, TASK.workspace_high)


def test_workspace_holds_the_paper_points_and_starts():
    lo, hi = TASK.workspace_low, TASK.workspace_high
    for p in (TASK.plate, TASK.cup, TASK.start):
        assert (p >= lo).all() and (p <= hi).all()
    starts = TASK.sample_start(np.random.default_rng(0), 500)
    assert starts.shape == (500, 3) and (starts >= lo).all() and (starts <= hi).all()
    np.testing.assert_array_equal(TASK.prior_modes, ROBOT_MODES)
    assert TASK.alpha == 2.0


def test_task_pickles_and_with_prior_keeps_geometry():
    from strol_gym.priors import UniformPrior

    t = pickle.loads(pickle.dumps(TASK.with_prior(UniformPrior(2))))
    x = np.random.default_rng(1).uniform(0, 0.5, (7, 3))
    np.testing.assert_array_equal(t.features(x), TASK.features(x))
    assert t.prior.name == "uniform"


# ------------------------------------------------------------------------------ the planner
def _problems(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    theta = np.concatenate([TASK.prior.sample(rng, n // 2), rng.uniform(-1, 1, (n - n // 2, 2))])
    x0 = TASK.sample_start(rng, n)
    return theta, x0


def _ret(plans: np.ndarray, theta: np.ndarray) -> np.ndarray:
    return TASK.reward(plans[:, 1:], theta[:, None]).sum(axis=1)


def test_plans_are_feasible_and_start_at_x0():
    theta, x0 = _problems(40)
    plans = TASK.plan(theta, x0)
    assert plans.shape == (40, TASK.plan_steps + 1, 3)
    np.testing.assert_array_equal(plans[:, 0], x0)
    assert np.abs(np.diff(plans, axis=1)).max() <= TASK.plan_step_bound + 1e-12
    assert (plans >= TASK.workspace_low - 1e-12).all()
    assert (plans <= TASK.workspace_high + 1e-12).all()


def test_plan_is_deterministic_and_row_independent():
    theta, x0 = _problems(12, seed=3)
    batch = TASK.plan(theta, x0)
    np.testing.assert_array_equal(batch, TASK.plan(theta, x0))
    for i in (0, 5, 11):
        np.testing.assert_allclose(TASK.plan(theta[i], x0[i])[0], batch[i], atol=1e-12)


def test_regret_zero_for_the_true_weights_positive_for_mirrored():
    theta, x0 = _problems(30, seed=1)
    np.testing.assert_array_equal(TASK.regret(theta, theta, x0), 0.0)
    assert (TASK.regret(-theta, theta, x0) > 0).all()


def test_plan_beats_its_simple_starts_and_local_perturbations():
    """No straight line (towards/away from an object, or standing still) and no small feasible
    perturbation of the plan does better: the ascent reached a (local) optimum."""
    theta, x0 = _problems(20, seed=2)
    plans = TASK.plan(theta, x0)
    best = _ret(plans, theta)
    targets = np.stack([TASK.plate, TASK.cup])
    lines = straight_line_starts(x0, targets, TASK.plan_steps, TASK.plan_step_bound)
    for k in range(lines.shape[1]):
        for sign in (1, -1):
            way = np.clip(
                x0[:, None] + np.cumsum(sign * lines[:, k], axis=1),
                TASK.workspace_low,
                TASK.workspace_high,
            )
            plan = np.concatenate([x0[:, None], way], axis=1)
            assert (best >= _ret(plan, theta) - 1e-9).all()
    assert (best >= _ret(np.repeat(x0[:, None], TASK.plan_steps + 1, 1), theta) - 1e-9).all()
    rng = np.random.default_rng(0)
    for _ in range(50):
        inc = np.diff(plans, axis=1) + rng.normal(0, 0.004, (20, TASK.plan_steps, 3))
        inc = np.clip(inc, -TASK.plan_step_bound, TASK.plan_step_bound)
        way = np.clip(x0[:, None] + np.cumsum(inc, axis=1), TASK.workspace_low, TASK.workspace_high)
        other = np.concatenate([x0[:, None], way], axis=1)
        assert (_ret(other, theta) <= best + 2e-3).all()


def test_planner_keeps_the_box_inside_the_optimisation():
    """θ wants to go up and away: waypoints sit on the box's top face, not beyond it and then
    clipped, so the plan's return is exactly what the optimiser maximised."""
    x0 = np.array([[0.3, 0.0, 0.65]])
    theta = np.array([[0.0, -1.0]])  # far from the cup
    plan = TASK.plan(theta, x0)[0]
    assert plan[:, 2].max() <= TASK.workspace_high[2] + 1e-12
    assert plan[-1, 2] == pytest.approx(TASK.workspace_high[2])


def test_robot_policy_is_the_first_planned_step():
    theta, x0 = _problems(5, seed=4)
    u = TASK.robot_policy(x0, theta)
    np.testing.assert_allclose(u, TASK.plan(theta, x0)[:, 1] - x0)
    assert np.abs(u).max() <= TASK.plan_step_bound + 1e-12


def test_generic_planner_validates_and_widens_box_for_outside_starts():
    f, j = TASK.features, TASK.feature_jacobian
    kw = {"steps": 4, "step_bound": 0.05, "low": TASK.workspace_low, "high": TASK.workspace_high}
    with pytest.raises(ValueError, match="batch"):
        plan_linear_reward(f, j, np.zeros((2, 2)), np.zeros((3, 3)), **kw)
    with pytest.raises(ValueError, match="step_bound"):
        plan_linear_reward(f, j, np.zeros((1, 2)), np.zeros((1, 3)), **{**kw, "step_bound": 0})
    outside = np.array([[0.0, 0.0, 0.3]])  # x below the box
    plan = plan_linear_reward(f, j, np.array([[1.0, 0.0]]), outside, **kw)
    assert np.abs(np.diff(plan, axis=1)).max() <= 0.05 + 1e-12
