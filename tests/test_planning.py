"""Batching the planners: a row's plan and regret do not depend on the rest of the batch.

The benchmark runner scores a whole unit of episodes with one ``Task.regret`` call and
deduplicates equal (θ, x0) rows; results must be the very numbers a call per episode gives.
"""

from __future__ import annotations

import numpy as np
import pytest

from strol_gym.planning import _Buffers
from strol_gym.tasks import make_task
from strol_gym.tasks.base import unique_rows

PLANNING_TASKS = ("robot", "study-task1", "study-task2", "study-task1-v2", "study-task2-v2")
"""v2's planner walks its plans out of the hulls: whether a round of that walk ran must be
decided per θ, not per batch (it was once: 1e-16 apart, then another start chosen)."""


def _problems(task, n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    theta_hat = rng.uniform(-1.0, 1.0, (n, task.dim))
    theta_star = rng.uniform(-1.0, 1.0, (n, task.dim))
    return theta_hat, theta_star, task.sample_start(rng, n)


@pytest.mark.parametrize("name", PLANNING_TASKS)
def test_plan_of_a_row_is_bit_identical_alone_and_in_a_batch(name):
    task = make_task(name)
    theta, _, x0 = _problems(task, 8, seed=11)
    batch = task.plan(theta, x0)
    for i in range(len(theta)):
        np.testing.assert_array_equal(task.plan(theta[i], x0[i])[0], batch[i])


@pytest.mark.parametrize("name", PLANNING_TASKS)
def test_batched_regret_with_shared_rows_equals_one_call_per_episode(name):
    task = make_task(name)
    theta_hat, theta_star, x0 = _problems(task, 3, seed=5)
    # Every θ̂ against every (θ*, x0): the θ* rows repeat, as for four learners on one seed.
    hat = np.repeat(theta_hat, 3, axis=0)
    star, start = np.tile(theta_star, (3, 1)), np.tile(x0, (3, 1))
    batched = task.regret(hat, star, start)
    single = [task.regret(h, s, x)[0] for h, s, x in zip(hat, star, start, strict=True)]
    np.testing.assert_array_equal(batched, single)


def test_unique_rows_compares_exact_bytes_across_arrays():
    a = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, -0.0], [2.0, 0.0]])
    b = np.array([[5.0], [5.0], [5.0], [5.0]])
    first, inverse = unique_rows(a, b)
    assert first.tolist() == [0, 2, 3]  # −0.0 is not merged with 0.0
    assert inverse.tolist() == [0, 0, 1, 2]
    b2 = np.array([[5.0], [6.0], [5.0], [5.0]])
    first, inverse = unique_rows(a, b2)  # the second array separates rows 0 and 1
    assert first.tolist() == [0, 1, 2, 3]
    np.testing.assert_array_equal(
        np.vstack([a, a])[unique_rows(np.vstack([a, a]))[0]], a[[0, 2, 3]]
    )


def test_theta_weighted_jacobian_sums_in_feature_order_and_agrees_with_matmul():
    rng = np.random.default_rng(2)
    b, n, steps, d, s = 3, 4, 5, 3, 3
    theta = rng.uniform(-1.0, 1.0, (b, d))
    jac = rng.normal(size=(b, n, steps, d, s))
    theta[0] = [0.5, 0.7, 0.2]
    jac[0, 0, 0] = -0.0  # every product −0: a sum from +0 gives +0
    jac[1, 1, 1, :, 0] = [1.0, -1.0, 0.0]
    theta[1] = [1.0, 1.0, 0.5]  # an exact cancellation
    box = _Buffers(theta, np.zeros((b, s)), np.full(s, -1.0), np.ones(s), n, steps)
    got = box.ascent(jac).copy()
    # Our arithmetic is elementwise IEEE operations, the same bits on every CPU: the products
    # summed in feature order from +0, as Python floats do.
    exact = np.empty_like(got)
    for idx in np.ndindex(got.shape):
        total = 0.0
        for i in range(d):
            total += float(theta[idx[0], i]) * float(jac[(*idx[:-1], i, idx[-1])])
        exact[idx] = total
    assert got.tobytes() == exact.tobytes()
    assert not np.signbit(got[0, 0, 0]).any()
    # BLAS sums in an order of its kernel's choosing: equal within the rounding of a 3-term dot
    # product (|error| ≤ 3·u·Σ|θ_i J_i| for each side), not bit for bit.
    want = np.matmul(theta[:, None, None, None, :], jac)[..., 0, :]
    bound = 6 * np.finfo(float).eps / 2 * np.einsum("bi,bnsic->bnsc", np.abs(theta), np.abs(jac))
    assert np.all(np.abs(got - want) <= bound)


def test_robot_features_and_jacobian_large_batches_equal_the_small_path():
    task = make_task("robot")
    x = task.sample_start(np.random.default_rng(4), 1200).reshape(40, 30, 3)
    x[0, :5] = task.cup  # the kink: zero distance
    phi, jac = task.features(x), task.feature_jacobian(x)
    assert x.size >= 3000  # the large path (strol_gym.tasks.robot._LONG)
    # C order as on the small path: sums over φ reduce in memory order (returns, plan values).
    assert phi.flags.c_contiguous
    for i in (0, 17, 39):
        assert task.features(x[i]).tobytes() == phi[i].tobytes()
        assert task.feature_jacobian(x[i]).tobytes() == np.ascontiguousarray(jac[i]).tobytes()
