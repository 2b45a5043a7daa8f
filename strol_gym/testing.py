"""Checks a researcher runs on their own pieces before plugging them into strol-gym.

``check_task(task)``, ``check_learner(learner, task)`` and ``check_human(human, task)`` exercise
a piece the way the envs, the wrapper, training and the benchmark will: shapes, batching,
determinism, finiteness, state round trips, and the agreement of batched and per-sample calls.
Each raises ``AssertionError`` with a message that names the broken property (or the piece's
own ``ValueError``); each returns nothing when all is well. strol-gym's own tests run them on
every registered piece.
"""

from __future__ import annotations

import json
import pickle
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from strol_gym.humans import Human, HumanFactory, human_model, make_human
from strol_gym.tasks.base import Task

__all__ = ["check_human", "check_learner", "check_task"]

_SEED = 1_390  # a diagnostics seed (the project keeps 1000-1399 for diagnostics)


def _fail(what: str, detail: str) -> None:
    raise AssertionError(f"{what}: {detail}")


def _shape(what: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != shape:
        _fail(what, f"expected shape {shape}, got {arr.shape}")
    if not np.isfinite(arr).all():
        _fail(what, f"must be finite, got {arr}")
    return arr


def _close(what: str, a: ArrayLike, b: ArrayLike, atol: float = 1e-9) -> None:
    if not np.allclose(a, b, rtol=1e-7, atol=atol):
        _fail(what, f"{np.asarray(a).tolist()} != {np.asarray(b).tolist()}")


def _samples(task: Task, n: int, seed: int = _SEED) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """n start states, human actions and robot actions, all admissible, from one seed."""
    rng = np.random.default_rng(seed)
    x = task.sample_start(rng, n)
    u_h = rng.uniform(-1.0, 1.0, (n, task.action_dim)) * task.action_bound
    u_r = rng.uniform(-1.0, 1.0, (n, task.action_dim)) * task.robot_action_bound
    return x, u_h, u_r


# ---------------------------------------------------------------------------------- Tasks
def check_task(task: Task, *, n: int = 8, plan: bool = True) -> None:
    """Check a Task: the class attributes, bounds, prior, start states, φ, f, g, candidates,
    reward and (if it has one) its planner, batched and per sample, and that it pickles.

    ``plan=False`` skips the planner (regret, robot policy), the slowest part.
    """
    if not isinstance(task, Task):
        _fail("task", f"must be a strol_gym.tasks.Task instance, got {type(task).__name__}")
    name = type(task).__name__
    for attr in ("task_id", "version", "feature_names", "state_dim", "action_dim"):
        if not hasattr(task, attr):
            _fail(name, f"class attribute {attr!r} is missing")
    d, s, a = task.dim, task.state_dim, task.action_dim
    if d < 1 or s < 1 or a < 1:
        _fail(name, f"dim, state_dim and action_dim must be >= 1, got {d}, {s}, {a}")
    for attr in ("action_bound", "robot_action_bound"):
        bound = _shape(f"{name}.{attr}", getattr(task, attr), (a,))
        if (bound <= 0).any():
            _fail(f"{name}.{attr}", f"must be > 0 per axis, got {bound}")
    modes = np.asarray(task.prior_modes, dtype=np.float64)
    if modes.ndim != 2 or modes.shape[1] != d or not np.isfinite(modes).all():
        _fail(f"{name}.prior_modes", f"must be finite with shape (k, {d}), got {modes.shape}")
    scale = _shape(f"{name}.feature_scale", task.feature_scale, (d,))
    if (scale <= 0).any():
        _fail(f"{name}.feature_scale", f"must be > 0, got {scale}")
    if task.prior.dim != d:
        _fail(f"{name}.prior", f"has dim {task.prior.dim}, the task has {d} features")

    def draw(seed: int) -> tuple[np.ndarray, np.ndarray]:
        rng = np.random.default_rng(seed)
        return task.prior.sample(rng, n), task.sample_start(rng, n)

    th, x0 = draw(_SEED)
    _shape(f"{name}.prior.sample(rng, {n})", th, (n, d))
    _shape(f"{name}.sample_start(rng, {n})", x0, (n, s))
    th2, x02 = draw(_SEED)
    if not (np.array_equal(th, th2) and np.array_equal(x0, x02)):
        _fail(name, "prior.sample / sample_start are not deterministic given the generator")

    x, u_h, u_r = _samples(task, n)
    phi = _shape(f"{name}.features on (n, state_dim)", task.features(x), (n, d))
    for i in range(n):
        _close(f"{name}.features: batched row {i} vs a single state", phi[i], task.features(x[i]))
    if (phi > task.feature_high + 1e-12).any():
        _fail(f"{name}.features", f"exceed feature_high = {task.feature_high}: {phi.max()}")
    xn = _shape(f"{name}.dynamics on batches", task.dynamics(x, u_h, u_r), (n, s))
    for i in range(n):
        _close(f"{name}.dynamics: batched row {i}", xn[i], task.dynamics(x[i], u_h[i], u_r[i]))
    g = _shape(f"{name}.g on batches", task.g(x, u_h, u_r), (n, d))
    for i in range(n):
        _close(f"{name}.g: batched row {i} vs a single sample", g[i], task.g(x[i], u_h[i], u_r[i]))
    zero = task.g(x, np.zeros_like(u_h), u_r)
    _close(f"{name}.g(x, 0, u_R) (no correction, nothing to learn) must be 0", zero, 0 * zero)
    # g broadcasts over candidate actions, as the eq. M6 human evaluates it: (n, k, a).
    rng = np.random.default_rng(_SEED + 1)
    cand = task.candidate_actions(rng, n, 5)
    _shape(f"{name}.candidate_actions(rng, {n}, 5)", cand, (n, 6, a))
    if (np.abs(cand) > np.asarray(task.action_bound) + 1e-12).any():
        _fail(f"{name}.candidate_actions", "leave the admissible box |u| <= action_bound")
    gk = _shape(
        f"{name}.g over candidates (n, k, a)",
        task.g(x[:, None, :], cand, u_r[:, None, :]),
        (n, 6, d),
    )
    _close(f"{name}.g over candidates vs per candidate", gk[:, 3], task.g(x, cand[:, 3], u_r))
    # The same numbers feature-first, as eq. M6's search reads them (a Task may override it).
    planes = _shape(
        f"{name}.g_planes over candidates (d, n, k)",
        task.g_planes(x[:, None, :], cand, u_r[:, None, :]),
        (d, n, 6),
    )
    _close(f"{name}.g_planes vs g", np.moveaxis(planes, 0, -1), gk)
    theta = th
    _close(
        f"{name}.reward(x, θ) must be θ·φ(x)",
        task.reward(x, theta),
        np.sum(phi * theta, axis=-1),
    )
    z = task.network_input(x, u_h, u_r)
    _shape(f"{name}.network_input", z, (n, task.network_input_dim))
    try:
        json.dumps(task.describe())
    except (TypeError, ValueError) as e:
        _fail(f"{name}.describe()", f"must be JSON-serialisable ({e})")
    again = pickle.loads(pickle.dumps(task))
    _close(f"{name} after a pickle round trip: features", again.features(x), phi)
    if plan:
        _check_planner(task, name, x, theta)


def _check_planner(task: Task, name: str, x: np.ndarray, theta: np.ndarray) -> None:
    try:
        regret = task.regret(theta[:2], theta[:2], x[:2])
    except NotImplementedError:
        return  # no planner: the benchmark reports regret as NaN, which is allowed
    _shape(f"{name}.regret(θ*, θ*, x0) (B,)", regret, (2,))
    if np.abs(regret).max() > 1e-6:
        _fail(f"{name}.regret", f"of θ* against itself must be 0, got {regret}")
    u = _shape(
        f"{name}.robot_policy (B, a)", task.robot_policy(x[:2], theta[:2]), (2, task.action_dim)
    )
    if (np.abs(u) > np.asarray(task.robot_action_bound) + 1e-9).any():
        _fail(f"{name}.robot_policy", f"exceeds robot_action_bound: {u}")


# ---------------------------------------------------------------------------------- learners
def check_learner(
    learner: Any, task: Task, *, n: int = 4, batch: bool = True, **kwargs: Any
) -> None:
    """Check a learner (a class, a factory ``(task=, **kwargs)``, a registered name or a
    ``"module:attr"``) on ``task``: θ̂'s shape, finiteness and start, ``update`` on single
    samples and (``batch=True``, as the interface asks) on batches that agree with them,
    determinism, and the ``state_dict`` round trip. ``kwargs`` go to the factory.
    """
    from strol_gym.learners.protocol import OnlineRewardLearner
    from strol_gym.learners.registry import make_learner

    def build() -> Any:
        obj = make_learner(learner, task=task, **kwargs)
        if not isinstance(obj, OnlineRewardLearner):
            _fail(str(learner), "does not have the OnlineRewardLearner interface")
        return obj

    name = getattr(learner, "__name__", str(learner))
    d = task.dim
    x, u_h, u_r = _samples(task, n)
    one, two = build(), build()
    if one is two:
        _fail(name, "the factory must build a fresh learner each call, not return one object")
    theta0 = _shape(f"{name}.reset()", one.reset(), (d,))
    _close(f"{name}.theta after reset()", one.theta, theta0)
    two.reset()
    path = []
    for i in range(n):
        path.append(_shape(f"{name}.update (step {i})", one.update(x[i], u_h[i], u_r[i]), (d,)))
        _close(f"{name}.theta after update (step {i})", one.theta, path[-1])
        _close(
            f"{name}: same inputs, same θ̂ (determinism, step {i})",
            two.update(x[i], u_h[i], u_r[i]),
            path[-1],
        )
    state = one.state_dict()
    three = build()
    three.load_state_dict(state)
    _close(f"{name}.load_state_dict(state_dict()): θ̂", three.theta, one.theta)
    nxt = one.update(x[0], u_h[0], u_r[0])
    _close(
        f"{name}: after load_state_dict, the next update", three.update(x[0], u_h[0], u_r[0]), nxt
    )
    start = np.asarray(theta0) + 0.1 * np.arange(d)
    _close(f"{name}.reset(theta0)", one.reset(start), start)
    if batch:
        solo = []
        for i in range(n):
            one.reset(start)
            solo.append(one.update(x[i], u_h[i], u_r[i]))
        four = build()
        four.reset(np.tile(start, (n, 1)))
        got = _shape(f"{name}.update on a batch of {n}", four.update(x, u_h, u_r), (n, d))
        _close(f"{name}: a batched update vs {n} single updates", got, np.stack(solo), atol=1e-6)


# ---------------------------------------------------------------------------------- humans
def check_human(
    human: str | HumanFactory,
    task: Task,
    *,
    sigma: float = 0.1,
    bias: float = 0.0,
    beta: float = 50.0,
    steps: int = 3,
    **human_kwargs: Any,
) -> None:
    """Check a human (a registered name, a ``"module:attr"`` or a factory) on ``task``: it is
    built as the envs build it (σ, ε, β and ``human_kwargs``, only those it declares), exposes
    ``theta_star`` (d,), answers ``act`` with ``action_dim`` finite numbers and draws its
    randomness from the generator it is given (same seed, same corrections); its batched model
    (``humans.human_model``) answers a batch of ``steps`` people with finite corrections."""
    theta_star = np.asarray(task.prior_modes, dtype=np.float64)[0]
    x, _, u_r = _samples(task, steps)
    theta_hat = np.asarray(task.prior_modes, dtype=np.float64).mean(axis=0)
    runs = []
    for _ in range(2):
        h = make_human(
            human,
            task,
            theta_star.copy(),
            np.random.default_rng(_SEED),
            sigma=sigma,
            bias=bias,
            beta=beta,
            **human_kwargs,
        )
        if not isinstance(h, Human):
            _fail(str(human), "must build an object with act(x, u_r, theta_hat) and theta_star")
        _shape(f"{human}.theta_star", h.theta_star, (task.dim,))
        runs.append(
            [
                _shape(
                    f"{human}.act (step {i})", h.act(x[i], u_r[i], theta_hat), (task.action_dim,)
                )
                for i in range(steps)
            ]
        )
    _close(f"{human}: the same generator seed must give the same corrections", runs[0], runs[1])
    model = human_model(human, task, sigma=sigma, bias=bias, beta=beta, **human_kwargs)
    stars = np.broadcast_to(theta_star, (steps, task.dim))
    hats = np.broadcast_to(theta_hat, (steps, task.dim))
    batch = model.correct(x, u_r, stars, np.random.default_rng(_SEED), hats)
    _shape(f"{human}: its model's corrections of a batch", batch, (steps, task.action_dim))
