"""Property tests (hypothesis): Gradient never moves away from θ* under a noise-free eq. M6
human, and ‖ĝ‖ ≤ ‖g‖ holds for any network, input and g."""

from __future__ import annotations

import numpy as np
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from strol_gym import RobotTask
from strol_gym.humans import optimal_correction
from strol_gym.learners.correction import StROLLearner
from strol_gym.learners.network import CorrectionNet, bound_correction
from strol_gym.learners.rules import GradientLearner

TASK = RobotTask()
SHIPPED = StROLLearner(TASK)
seeds = st.integers(min_value=0, max_value=2**32 - 1)


@settings(max_examples=60, deadline=None)
@given(seed=seeds, k=st.integers(0, 64), spread=st.floats(0.0, 3.0))
def test_gradient_never_increases_error_with_noise_free_m6_human(seed, k, spread):
    rng = np.random.default_rng(seed)
    n = 8
    x = TASK.sample_start(rng, n)
    theta_star = spread * rng.standard_normal((n, TASK.dim))
    theta_hat = spread * rng.standard_normal((n, TASK.dim))
    u_r = rng.uniform(-1, 1, (n, 3)) * TASK.robot_action_bound
    cand = TASK.candidate_actions(rng, n, k)  # index 0 is the zero action
    assert np.all(cand[:, 0] == 0)
    u_h = optimal_correction(TASK, x, u_r, theta_hat, theta_star, cand)
    learner = GradientLearner(TASK)
    learner.reset(theta_hat)
    after = learner.update(x, u_h, u_r)
    before_err = np.linalg.norm(theta_star - theta_hat, axis=-1)
    after_err = np.linalg.norm(theta_star - after, axis=-1)
    assert np.all(after_err <= before_err + 1e-12)


@settings(max_examples=100, deadline=None)
@given(
    seed=seeds,
    scale=st.floats(1e-3, 1e4),
    # g = 0 exactly, or a scale whose squared norm is a normal float in float32 as well: below
    # about 1e-19 (float32) or 1e-154 (float64) the squares underflow to subnormals, vector_norm
    # loses ~1e-3 of relative precision and no 1e-6 margin can be measured (such g are zero
    # for every Task: φ differences are 1e-4 and up).
    g_scale=st.one_of(st.just(0.0), st.floats(1e-6, 1e3)),
    bound=st.sampled_from(["radial", "box"]),
    d=st.integers(1, 5),
)
def test_correction_bound_holds_for_any_network(seed, scale, g_scale, bound, d):
    gen = torch.Generator().manual_seed(seed)
    net = CorrectionNet(4, d, hidden=(16, 8), bound=bound)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(scale * torch.randn(p.shape, generator=gen))
    z = scale * torch.randn(32, 4, generator=gen)
    g = g_scale * torch.randn(32, d, generator=gen, dtype=torch.float64)
    g[0] = 0.0
    g_hat = net(z, g)
    assert torch.all(torch.linalg.vector_norm(g_hat, dim=-1) <= torch.linalg.vector_norm(g, dim=-1))
    # The same in float32 (the training path).
    g32 = g.float()
    g_hat32 = bound_correction(net.raw(z), g32, bound)
    norms = torch.linalg.vector_norm(g_hat32, dim=-1)
    assert torch.all(norms <= torch.linalg.vector_norm(g32, dim=-1))


@settings(max_examples=60, deadline=None)
@given(seed=seeds, size=st.floats(0.0, 5.0))
def test_shipped_strol_correction_is_bounded_by_g(seed, size):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1.0, 2.0, (16, 3))  # also outside the workspace
    u_h = size * rng.uniform(-1, 1, (16, 3)) * TASK.action_bound
    u_r = rng.uniform(-1, 1, (16, 3)) * TASK.robot_action_bound
    g_hat = SHIPPED.correction(x, u_h, u_r)
    g = TASK.g(x, u_h, u_r)
    assert np.all(np.linalg.norm(g_hat, axis=-1) <= np.linalg.norm(g, axis=-1))
