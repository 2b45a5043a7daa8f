"""The compiled kernels (``strol_gym.compiled``, the ``[fast]`` extra) against the plain path:
the same bytes on fixed seeds. Both paths run in this process (``compiled.FAST`` flipped)."""

from __future__ import annotations

import hashlib
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import strol_gym.compiled as compiled
from strol_gym.envs.panda.ik import PandaIK, solver
from strol_gym.humans.choices import optimal_correction
from strol_gym.tasks.highway import HighwayTask
from strol_gym.tasks.robot import RobotTask

pytest.importorskip("numba")


@pytest.fixture
def path(monkeypatch):
    """``path(True)`` turns the compiled kernels on, ``path(False)`` off, for this test."""

    def switch(fast: bool) -> None:
        monkeypatch.setattr(compiled, "FAST", fast)

    return switch


@pytest.mark.parametrize("task", [RobotTask(), HighwayTask()], ids=["robot", "highway"])
def test_eq_m6_choices_are_the_plain_searchs(task, path):
    rng = np.random.default_rng(40)
    for trial in range(60):
        b = 1 if trial % 2 else 17
        x = task.sample_start(rng, b)
        if isinstance(task, HighwayTask) and trial % 3 == 0:
            x[:, 6] = rng.choice([45.0, -45.0, 25.0], b)  # the speed clip of _car_step
        u_r = rng.uniform(-1.5, 1.5, (b, task.action_dim)) * task.action_bound  # some clipped
        theta_hat, theta_star = rng.standard_normal((2, b, task.dim))
        cand = task.candidate_actions(rng, b, 512)
        path(False)
        plain = optimal_correction(task, x, u_r, theta_hat, theta_star, cand)
        path(True)
        fast = optimal_correction(task, x, u_r, theta_hat, theta_star, cand)
        assert fast.tobytes() == plain.tobytes()


@pytest.mark.parametrize("task", [RobotTask(), HighwayTask()], ids=["robot", "highway"])
def test_a_nan_norm_is_chosen_first_as_numpys_argmin_does(task, path):
    rng = np.random.default_rng(1)
    x = task.sample_start(rng, 2)
    u_r = np.zeros((2, task.action_dim))
    theta_hat = np.zeros((2, task.dim))
    theta_hat[0, 0] = np.nan
    cand = task.candidate_actions(rng, 2, 16)
    path(False)
    plain = optimal_correction(task, x, u_r, theta_hat, np.ones((2, task.dim)), cand)
    path(True)
    fast = optimal_correction(task, x, u_r, theta_hat, np.ones((2, task.dim)), cand)
    assert fast.tobytes() == plain.tobytes()
    assert (fast[0] == cand[0, 0]).all()


def test_the_highway_search_skips_only_candidates_that_cannot_be_picked(path):
    """The Highway's screen drops only candidates that cannot be picked: ties keep the first
    minimum, and a NaN or unbounded input (where a dropped norm could be NaN) turns it off."""
    task = HighwayTask()
    rng = np.random.default_rng(33)
    x = task.sample_start(rng, 6)
    u_r = rng.uniform(-1, 1, (6, 2)) * task.action_bound
    theta_hat, theta_star = rng.standard_normal((2, 6, 3))
    theta_hat[:, 1] = theta_star[:, 1]  # the speed term small: few skips, many near ties
    cand = task.candidate_actions(rng, 6, 256)
    cand[0, 200:] = cand[0, 100:157]  # exact repeats: the first of equal norms wins
    cand[1, 180, 0] = np.nan  # a NaN candidate: numpy's argmin stops there
    x[2, 6] = 1e200  # an unbounded speed: intermediates overflow
    x[3, 0] = np.inf
    cand[4, 90:, 1] = cand[4, 90, 1]  # equal steering: their norms differ by speed alone
    path(False)
    with np.errstate(all="ignore"):  # the overflows and the NaN are the point
        plain = optimal_correction(task, x, u_r, theta_hat, theta_star, cand)
    path(True)
    fast = optimal_correction(task, x, u_r, theta_hat, theta_star, cand)
    assert fast.tobytes() == plain.tobytes()
    assert np.isnan(fast[1]).any()  # the NaN candidate was reached and chosen, as numpy does


@pytest.mark.parametrize(
    "task", [HighwayTask(), HighwayTask(max_steering=0.2)], ids=["default", "wide-steering"]
)
def test_the_highway_screen_keeps_every_candidate_that_could_be_chosen(task, path):
    """The screen (polynomials for the trigonometry, a proven error bound) drops most
    candidates and never the chosen one: near ties, exact repeats, angles at the edge of the
    polynomials' range, steering beyond it, far positions and clipped speeds included."""
    from strol_gym.tasks.m6_kernels import highway_m6_screen

    rng = np.random.default_rng(56)
    kept = total = settled = 0
    for trial in range(40):
        b = 16
        x = task.sample_start(rng, b)
        x[:4, 7] = rng.choice([0.45, -0.45, 0.3], 4)  # headings near the range's edge
        x[4:6, [0, 4]] += 9e3  # far down the road
        x[6, 6] = 45.0  # the speed clip
        u_r = rng.uniform(-1.2, 1.2, (b, 2)) * task.action_bound
        u_r[7, 1] = 0.06  # a robot steering beyond the polynomial's range
        cand = task.candidate_actions(rng, b, 256)
        cand[:, 200:230] = cand[:, 100:130]  # exact repeats: the first of equal norms wins
        cand[:, 231, 0] = np.nextafter(cand[:, 101, 0], np.inf)  # a hair from another
        theta_star = rng.standard_normal((b, 3))
        # θ̂ one correction away from θ*: the best norm near zero, its rivals near it
        g = task.g(x, cand[np.arange(b), rng.integers(1, 257, b)], u_r)
        theta_hat = theta_star - task.alpha * g + rng.normal(0, 1e-9, (b, 3)) * (trial % 2)
        path(False)
        plain = optimal_correction(task, x, u_r, theta_hat, theta_star, cand)
        path(True)
        fast = optimal_correction(task, x, u_r, theta_hat, theta_star, cand)
        assert fast.tobytes() == plain.tobytes()
        keep = np.empty(cand.shape[:2], dtype=bool)
        steer = np.empty(b * (cand.shape[1] + 1))
        best = np.empty(b, dtype=np.int64)
        prm = task._kernel_params
        highway_m6_screen(x, u_r, theta_hat, theta_star, cand, prm, keep, steer, best)
        kept, total = kept + keep[8:].sum(), total + keep[8:].size
        settled += (best[8:] >= 0).sum()  # one candidate left: the screen's choice
    if task.max_steering < 0.05:
        assert kept < total / 20 and settled > 40 * 8 / 2
    else:  # most candidates steer beyond the polynomials' range: kept for the exact search
        assert kept > total / 2


def test_highway_features_of_one_state_are_the_plain_bytes(path):
    task = HighwayTask()
    rng = np.random.default_rng(8)
    states = np.concatenate([task.sample_start(rng, 300), rng.uniform(-1e3, 1e3, (300, 8))])
    states[:5, 6] = np.nan
    states[5:10, 3] = np.inf
    with np.errstate(invalid="ignore"):
        for x in states:
            path(False)
            plain = task.features(x)
            path(True)
            assert task.features(x).tobytes() == plain.tobytes()


@pytest.mark.parametrize("task", [RobotTask(), HighwayTask()], ids=["robot", "highway"])
def test_candidates_scale_in_one_compiled_pass_to_the_plain_bytes(task, path):
    from strol_gym.humans.builtin import NominalModel

    model = NominalModel(task)
    out = []
    for fast in (False, True):
        path(fast)
        one = task.candidate_actions(np.random.default_rng(2), 1, 512)
        many = task.candidate_actions(np.random.default_rng(2), 9, 64)
        each = model.draw_each([np.random.default_rng(s) for s in range(9)]).candidates
        out.append(b"".join(a.tobytes() for a in (one, many, each)))
    assert out[0] == out[1]


def test_a_task_that_overrides_what_the_kernel_repeats_takes_the_plain_path(path):
    class Shifted(RobotTask):
        def features(self, x):
            return super().features(x) + 1.0

    path(True)
    task, x = Shifted(), np.zeros((1, 3))
    assert task.m6_choice(x, x, np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2, 3))) is None
    assert (
        RobotTask().m6_choice(x, x, np.zeros((1, 2)), np.ones((1, 2)), np.zeros((1, 2, 3)))[0] == 0
    )


@pytest.mark.parametrize("task_cls", [RobotTask, HighwayTask])
@pytest.mark.parametrize(("sigma", "bias"), [(0.0, 0.0), (0.3, -0.2)])
def test_the_drawn_correction_is_the_plain_draws_and_choice(task_cls, sigma, bias, path):
    """``NominalModel.drawn_corrections`` (one compiled call from each person's draws, by
    chunks of people) against ``draw_each`` and ``corrections`` on the plain path: the same
    bytes, the generators left in the same state; one person as ``act`` asks. On the Highway
    some people are left open by the screen (a robot steering beyond its polynomials, a NaN
    θ̂) and take the exact search."""
    from strol_gym.humans.builtin import DRAWN_CHUNK, NominalModel

    task = task_cls()
    model = NominalModel(task, sigma=sigma, bias=bias)
    rng = np.random.default_rng(5)
    a, d = task.action_dim, task.dim
    for b in (1, DRAWN_CHUNK + 5):
        x = task.sample_start(rng, b)
        u_r = rng.uniform(-1.5, 1.5, (b, a)) * task.action_bound  # some clipped
        if task_cls is HighwayTask:
            u_r[1::4, 1] = 0.2  # beyond the screen's steering range: the exact search
        theta_hat, theta_star = rng.standard_normal((2, b, d))
        theta_hat[0, 1] = np.nan if b > 1 else theta_hat[0, 1]  # argmin's NaN rule too
        seeds = rng.integers(0, 2**32, b)
        path(False)
        plain_rngs = [np.random.default_rng(s) for s in seeds]
        assert model.drawn_corrections(plain_rngs, x, u_r, theta_star, theta_hat) is None
        draws = model.draw_each(plain_rngs)
        plain = model.corrections(x, u_r, theta_star, draws, theta_hat)
        path(True)
        fast_rngs = [np.random.default_rng(s) for s in seeds]
        fast = model.drawn_corrections(fast_rngs, x, u_r, theta_star, theta_hat)
        assert fast is not None and fast.tobytes() == plain.tobytes()
        for a_rng, c_rng in zip(plain_rngs, fast_rngs, strict=True):
            assert a_rng.random() == c_rng.random()


def test_the_compiled_pcg64_uniforms_are_numpys():
    """``pcg64_fill.fill``: the doubles of ``Generator.random`` and the states after them, for
    lengths below, at and off its four-step chains; a generator of another kind is not taken."""
    from strol_gym.pcg64_fill import addresses, fill

    ours = [np.random.default_rng(s) for s in (0, 7, 2**40)]
    theirs = [np.random.default_rng(s) for s in (0, 7, 2**40)]
    for k in (1, 7, 8, 13, 1536):
        got = np.empty((3, k))
        fill(addresses(ours), got)
        want = np.stack([g.random(k) for g in theirs])
        assert got.tobytes() == want.tobytes()
    assert [g.bit_generator.state for g in ours] == [g.bit_generator.state for g in theirs]
    assert addresses([ours[0], np.random.Generator(np.random.Philox(1))]) is None


def test_the_compiled_mixture_draws_are_numpys(path):
    """``pcg64_fill.mixture``: ``integers(0, k)`` then ``standard_normal(d)`` per generator, the
    numbers and the states after them (the 32-bit draw's kept half carried into the next
    round; 5,000 normals of one generator reach the ziggurat's rare paths); the bimodal
    prior's θ* of many generators the same on both paths."""
    from strol_gym.pcg64_fill import addresses, mixture
    from strol_gym.priors import MixturePrior

    seeds = (0, 7, 2**40, 12)
    ours = [np.random.default_rng(s) for s in seeds]
    theirs = [np.random.default_rng(s) for s in seeds]
    for k, d in ((2, 2), (5, 3), (1, 2), (2, 1)):
        idx, z = np.empty(4, dtype=np.int64), np.empty((4, d))
        mixture(addresses(ours, ("mixture",)), k, idx, z)
        assert idx.tolist() == [g.integers(0, k) for g in theirs]
        assert z.tobytes() == np.stack([g.standard_normal(d) for g in theirs]).tobytes()
    z = np.empty((1, 5000))
    mixture(addresses(ours[:1], ("mixture",)), 1, idx[:1], z)
    assert z.tobytes() == theirs[0].standard_normal(5000).tobytes()
    assert [g.bit_generator.state for g in ours] == [g.bit_generator.state for g in theirs]
    prior, thetas = MixturePrior(np.array([[0.8, -0.8], [-0.8, 0.8], [0.0, 0.5]])), []
    for fast in (True, False):
        path(fast)
        thetas.append(prior.sample_each([np.random.default_rng(s) for s in seeds]).tobytes())
    assert thetas[0] == thetas[1]


def test_a_model_or_task_that_changes_what_the_drawn_kernel_repeats_draws_as_usual(path):
    from strol_gym.humans.builtin import NominalModel

    class Jittered(NominalModel):
        def draw_extra(self, rng, n):
            return {"jitter": rng.random((n, 1))}

    class Shifted(RobotTask):
        def candidate_actions(self, rng, n, k):
            return super().candidate_actions(rng, n, k) * 0.5

    path(True)
    x, th = np.zeros((1, 3)), np.zeros((1, 2))
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    assert Jittered(RobotTask()).drawn_corrections([rng], x, x, th, th) is None
    assert NominalModel(Shifted()).drawn_corrections([rng], x, x, th, th) is None
    assert NominalModel(RobotTask()).drawn_corrections([rng], x, x, th, None) is None
    assert rng.bit_generator.state == state  # nothing drawn
    assert NominalModel(RobotTask()).drawn_corrections([rng], x, x, th, th) is not None

    class Braking(HighwayTask):
        def candidate_actions(self, rng, n, k):
            return super().candidate_actions(rng, n, k) * 0.5

    x, u, th = np.zeros((1, 8)), np.zeros((1, 2)), np.zeros((1, 3))
    assert Braking().m6_drawn() is None and HighwayTask().m6_drawn() is not None
    state = rng.bit_generator.state
    assert NominalModel(Braking()).drawn_corrections([rng], x, u, th, th) is None
    assert rng.bit_generator.state == state


def _feed(h, value) -> None:
    """Every byte of an observation or info, with each value's type, dtype and shape."""
    h.update(type(value).__name__.encode())
    if isinstance(value, dict):
        for key, v in value.items():
            h.update(key.encode())
            _feed(h, v)
    elif isinstance(value, np.ndarray):
        h.update(f"{value.dtype}{value.shape}".encode() + value.tobytes())
    elif isinstance(value, bool | int | float | str | np.generic | tuple | list):
        h.update(repr(value).encode())


def _rollout(env_id: str, seed: int, steps: int, **kwargs) -> str:
    env = gym.make(env_id, **kwargs)
    h = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    _feed(h, obs)
    _feed(h, info)
    rng = np.random.default_rng(seed)
    for t in range(steps):
        action = rng.uniform(-1.2, 1.2, env.action_space.shape)
        if t % 3 == 0:
            env.unwrapped.set_theta_hat(rng.uniform(-1, 1, env.unwrapped.task.dim))
        obs, reward, term, trunc, info = env.step(action.astype(np.float32) if t % 2 else action)
        for part in (obs, reward, term, trunc, info):
            _feed(h, part)
        if env_id == "StROL-Robot-v0":
            h.update(env.unwrapped.data.qpos.tobytes() + env.unwrapped.data.ctrl.tobytes())
        if term or trunc:
            robot = env_id == "StROL-Robot-v0" and t % 7 == 0
            for part in env.reset(options={"state": [0.3, 0.0, 0.2]} if robot else None):
                _feed(h, part)
    env.close()
    return h.hexdigest()


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("StROL-Robot-v0", {}),
        ("StROL-Robot-v0", {"n_corrections": 0}),
        ("StROL-Robot-v0", {"person": {"name": "nominal", "sigma": 0.3, "bias": 0.1}}),
        ("StROL-Robot-v0", {"person": "changing", "n_corrections": 7}),
        ("StROL-Highway-v0", {}),
        ("StROL-Highway-v0", {"person": {"name": "changing", "sigma": 0.2, "bias": 0.1}}),
    ],
)
def test_env_rollouts_are_the_same_bytes_on_both_paths(env_id, kwargs, path):
    for seed in (3, 11):
        path(False)
        plain = _rollout(env_id, seed, 120, **kwargs)
        path(True)
        assert _rollout(env_id, seed, 120, **kwargs) == plain


def test_the_robot_step_runs_compiled_and_refuses_as_the_contract(path):
    """The Robot env's compiled step runs where its kernels do, not for an env class that
    changes a hook it repeats; a bad action raises as in the contract's step, before the
    person draws."""
    from strol_gym.envs.robot.env import RobotEnv

    path(True)
    env = RobotEnv()
    env.reset(seed=1)
    assert env._fused_step() is not None
    assert env._reset_draws(env.np_random) is not None  # θ* and the start drawn compiled
    uniform = RobotEnv(prior="uniform")
    assert uniform._reset_draws(uniform.np_random) is None
    state = env.np_random.bit_generator.state
    with pytest.raises(ValueError, match="action must be finite"):
        env.step(np.array([0.0, np.nan, 0.0]))
    assert env.np_random.bit_generator.state == state and env.steps == 0

    class Own(RobotEnv):
        def _terminated(self) -> bool:
            return self.steps > 2

    assert Own()._fused_step() is None
    path(False)
    assert RobotEnv()._fused_step() is None


def _limit_and_restart_cases(ik: PandaIK) -> list[tuple[np.ndarray, np.ndarray]]:
    """(start posture, target) pairs that drive the arm into joint limits and IK restarts."""
    rng = np.random.default_rng(7)
    q = rng.uniform(ik.lo, ik.hi, (60, 7))
    q[::3] = ik.hi - 1e-3  # at the upper limits
    q[1::3] = ik.lo + 1e-3
    targets = rng.uniform([-0.3, -0.9, -0.3], [1.2, 0.8, 1.1], (60, 3))  # some out of reach
    return list(zip(q, targets, strict=True))


def test_ik_solves_are_the_same_bytes_through_joint_limits_and_restarts(path, monkeypatch):
    env = gym.make("StROL-Robot-v0").unwrapped
    ik = env.ik
    limited = []
    update = PandaIK._update

    def counting(self, jp, jt, *args):
        limited.append(jp is jt)  # the limit step calls _update with J for both
        return update(self, jp, jt, *args)

    for q0, target in _limit_and_restart_cases(ik):
        path(False)
        monkeypatch.setattr(PandaIK, "_update", counting)
        ik.set_q(q0)
        err_plain = ik.solve(target)
        q_plain = ik.data.qpos.copy()
        monkeypatch.setattr(PandaIK, "_update", update)
        path(True)
        ik.set_q(q0)
        err_fast = ik.solve(target)
        assert np.float64(err_fast).tobytes() == np.float64(err_plain).tobytes()
        assert ik.data.qpos.tobytes() == q_plain.tobytes()
    assert sum(limited) > 10  # the limit step ran, not only free steps
    env.close()


def test_vector_envs_give_the_same_bytes_on_both_paths(path):
    for env_id in ("StROL-Robot-v0", "StROL-Highway-v0"):
        out = []
        for fast in (False, True):
            path(fast)
            env = gym.make_vec(env_id, 8, vectorization_mode="vector_entry_point")
            obs, _ = env.reset(seed=5)
            h = hashlib.sha256()
            rng = np.random.default_rng(5)
            for _ in range(25):
                obs, reward, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape))
                h.update(b"".join(np.asarray(obs[k]).tobytes() for k in sorted(obs)))
                h.update(np.asarray(reward).tobytes())
            env.close()
            out.append(h.hexdigest())
        assert out[0] == out[1], env_id


def _batched_cases(ik: PandaIK) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(start postures, targets, rows) for N = 300 arms: a large set (all compiled, or numpy then
    the compiled loop below a smaller handoff), targets out of reach (more than SINGLE_RETRY
    restarts: the batched restart; fewer: one arm at a time), postures at the joint limits, and
    one arm alone (numpy's sums for a batch of one)."""
    rng = np.random.default_rng(40)
    n = 300
    q = rng.uniform(ik.lo, ik.hi, (n, 7))
    q[::4] = ik.hi - 1e-3
    q[1::4] = ik.lo + 1e-3
    near = rng.normal((0.45, 0.0, 0.35), 0.12, (n, 3))
    far = rng.uniform([-0.3, -0.9, -0.3], [1.2, 0.8, 1.1], (n, 3))
    every = np.arange(n)
    return [
        (q, near, every),
        (q, far, every),
        (q, far[:40], np.arange(0, 200, 5)),
        (q, far[:1], np.array([7])),
        (q, near[:1], np.array([3])),
    ]


@pytest.mark.parametrize("handoff", [None, 192], ids=["compiled", "numpy-then-compiled"])
def test_batched_ik_solves_are_the_same_bytes_on_both_paths(path, monkeypatch, handoff):
    from strol_gym.envs.panda import ik_batched

    env = gym.make("StROL-Robot-v0").unwrapped
    restarts: list[int] = []
    solve = ik_batched.BatchedPandaIK._solve

    def counting(self, target, rows, iters, *args):
        if iters > ik_batched.IK_ITERS:
            restarts.append(len(rows))  # a batched restart
        return solve(self, target, rows, iters, *args)

    monkeypatch.setattr(ik_batched.BatchedPandaIK, "_solve", counting)
    out = []
    for fast in (False, True):
        path(fast)
        arms = ik_batched.BatchedPandaIK(env.ik, 300)
        if handoff is not None:  # sets above it iterate in numpy, then hand over
            arms._handoff = handoff
        h = hashlib.sha256()
        for q, target, rows in _batched_cases(env.ik):
            arms.q[:] = q
            arms.forward()
            h.update(arms.solve(target, rows).tobytes())
            a = arms._arms
            h.update(b"".join(x.tobytes() for x in (a.q, a.site, a.cols, a.axes, a.anchors)))
        out.append(h.hexdigest())
        assert (arms._kernels() is not None) == fast
    assert out[0] == out[1]
    assert max(restarts) > ik_batched.SINGLE_RETRY  # the batched restart ran
    env.close()


def test_the_robots_features_of_many_states_are_the_same_on_both_paths(path):
    """``RobotTask.features`` of (B, 3) states: the compiled loop gives numpy's bits below and
    above the size where numpy works per object and axis; a Task that changes its offsets
    keeps numpy's path."""

    class Shifted(RobotTask):
        def _offsets(self, x):
            return super()._offsets(x + 0.01)

    x = np.random.default_rng(9).uniform(-1.0, 1.5, (1100, 3))
    got = {}
    for fast in (False, True):
        path(fast)
        for n in (2, 999, 1100):
            got[fast, n] = RobotTask().features(x[:n]).tobytes()
        got[fast, "shifted"] = Shifted().features(x).tobytes()
    assert all(got[True, k] == got[False, k] for k in (2, 999, 1100, "shifted"))
    assert got[True, "shifted"] != got[True, 1100]


def test_the_batched_seed_lookup_is_the_same_on_both_paths(path):
    """``BatchedPandaIK.reference``: the seed table's posture nearest each target (outside the
    box: the nearest edge; a cell without a posture: NaN) on both paths."""
    from strol_gym.envs.panda import ik_batched

    env = gym.make("StROL-Robot-v0").unwrapped
    targets = np.random.default_rng(8).uniform(-0.5, 1.2, (2000, 3))
    got = []
    for fast in (False, True):
        path(fast)
        arms = ik_batched.BatchedPandaIK(env.ik, 4)
        arms.seeds = arms.seeds.copy()
        arms.seeds[::2, 1::3] = np.nan
        got.append(arms.reference(targets).tobytes())
        assert (arms._kernels() is not None) == fast
    assert got[0] == got[1]
    assert np.isnan(np.frombuffer(got[0])).any()
    env.close()


def test_an_arm_already_at_its_target_keeps_its_own_numbers_in_the_compiled_lanes(path):
    """An arm whose kinematics are MuJoCo's (a one-by-one restart) and that is within tolerance
    at the first check, while the other arms iterate, keeps its numbers in the compiled lanes
    (held, not recomputed by the batched forward kinematics), as the one-arm-at-a-time kernel
    before them did."""
    from strol_gym.envs.panda import ik_batched

    env = gym.make("StROL-Robot-v0").unwrapped
    path(True)
    arms = ik_batched.BatchedPandaIK(env.ik, 12)
    assert arms._kernels() is not None
    rows = np.arange(12)
    target = np.tile(env.ik.ee, (12, 1))
    target[0] = (2.0, 2.0, 2.0)  # out of reach: arm 0 restarts alone, on MuJoCo's model
    arms.solve(target, rows)
    a = arms._arms
    own = [x[..., 0].copy() for x in (a.q, a.site, a.cols, a.axes, a.anchors)]
    before = a.q.copy()
    target = arms.ee + np.linspace(-0.05, 0.05, 36).reshape(12, 3)
    target[0] = arms.ee[0]  # arm 0: there already
    arms.solve(target, rows)
    assert all((x[..., 0] == y).all() for x, y in zip(a._all(), own, strict=True))
    assert (a.q[:, 1:] != before[:, 1:]).any(axis=0).all()  # the others moved
    env.close()


def test_batched_kernels_that_miss_the_plain_bits_are_not_used(path, monkeypatch):
    from strol_gym.envs.panda import ik_batched, ik_lanes

    env = gym.make("StROL-Robot-v0").unwrapped
    path(True)
    monkeypatch.setattr(ik_batched, "_AGREES", None)
    real = ik_lanes.batched_forward

    def off_by_a_bit(q, site, *args):
        real(q, site, *args)
        site[0] = np.nextafter(site[0], np.inf)

    monkeypatch.setattr(ik_lanes, "batched_forward", off_by_a_bit)
    arms = ik_batched.BatchedPandaIK(env.ik, 4)
    assert arms._kernels() is None  # the check saw it: the plain path runs
    env.close()


def test_the_ik_kernel_is_there_where_numba_and_this_mujoco_are(path):
    path(True)
    assert solver() is not None
    path(False)
    assert solver() is None


def _mode_in_a_fresh_process(value: str, numba: bool = True) -> subprocess.CompletedProcess:
    code = "" if numba else "import sys; sys.modules['numba'] = None; "  # as if it failed to load
    code += "import strol_gym.compiled as c; print(c.kernels_in_use())"
    env = {"STROL_GYM_KERNELS": value, "PATH": ""}
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)


def test_the_switch_reads_its_variable_and_names_a_bad_value():
    assert _mode_in_a_fresh_process("plain").stdout.strip() == "plain"
    assert _mode_in_a_fresh_process("fast").stdout.strip() == "fast"
    assert _mode_in_a_fresh_process("auto").stdout.strip() == "fast"  # numba is here
    assert _mode_in_a_fresh_process("auto", numba=False).stdout.strip() == "plain"
    missing = _mode_in_a_fresh_process("fast", numba=False)
    assert "STROL_GYM_KERNELS=fast needs numba: pip install 'strol-gym[fast]'" in missing.stderr
    bad = _mode_in_a_fresh_process("turbo")
    assert bad.returncode != 0
    assert "STROL_GYM_KERNELS must be one of auto, plain, fast, got 'turbo'" in bad.stderr


def test_study_v2_plans_are_the_same_bytes_on_both_paths(path):
    from strol_gym.tasks.study import StudyTask1V2, StudyTask3V2

    rng = np.random.default_rng(56)
    for task in (StudyTask1V2(), StudyTask3V2()):  # upright; turning (Tasks 2-3 share it)
        for b in (1, 3):
            theta = rng.uniform(-1, 1, (b, task.dim))
            x0 = task.sample_start(rng, b)  # some inside a hull or outside the reachable box
            path(False)
            plain = task.plan(theta, x0)
            path(True)
            assert task.plan(theta, x0).tobytes() == plain.tobytes()


def test_the_study_walk_out_is_the_plain_bytes_in_any_batch(path):
    """Random plans from starts around the hulls, steps up to 3x the bound: the half-space
    pushes, the cuts and the waypoints held at a hull's surface all run."""
    from strol_gym.tasks.study import KEEP_OUT, StudyTask1V2, _walk_out

    task = StudyTask1V2()
    rng = np.random.default_rng(57)
    bound = task.plan_pos_bound
    low, high = task.low[:3], task.high[:3]
    x0 = rng.normal(KEEP_OUT[rng.integers(0, 2, 60), :3] * [1, 1, 0.5], 0.08)
    plans = x0[:, None, :] + np.cumsum(rng.uniform(-3, 3, (60, 21, 3)) * bound, axis=1)
    plans[:, 0] = x0
    path(False)
    plain = _walk_out(plans, KEEP_OUT, bound, low, high)
    clipped = _walk_out(plans, KEEP_OUT[:0], bound, low, high)  # the step box and box alone
    assert (np.abs(plain - clipped).max(-1) > 1e-9).mean() > 0.2  # the hulls moved many
    path(True)
    assert _walk_out(plans, KEEP_OUT, bound, low, high).tobytes() == plain.tobytes()
    for rows in (slice(0, 1), slice(7, 8), slice(10, 30)):  # alone or in another batch
        path(False)
        alone = _walk_out(plans[rows], KEEP_OUT, bound, low, high)
        path(True)
        assert _walk_out(plans[rows], KEEP_OUT, bound, low, high).tobytes() == alone.tobytes()


def _study_rollout(
    task: int, seed: int, steps: int, push: tuple[tuple[float, ...], tuple[float, ...], float]
) -> tuple[str, int]:
    """StROL-Study-v2 with its default person and a scripted push (force, torque, seconds) at
    step 10 (the brake, the reflexes, the counterfactual): (a hash of every step's
    observation, u_H and joint state, the brake's own chunks the plain path ran)."""
    from strol_gym.envs.study.controller import ImpedanceController

    env = gym.make("StROL-Study-v2", task=task).unwrapped
    braked = [0]
    chunk = ImpedanceController._braked_steps

    def counting(self, *args):
        braked[0] += 1
        return chunk(self, *args)

    env._braked_steps = counting.__get__(env)
    h = hashlib.sha256()
    env.reset(seed=seed)
    zero = np.zeros(env.action_space.shape, np.float32)
    for step in range(steps):
        if step == 10:
            env.apply_wrench(*push)
        obs, _, _, trunc, info = env.step(zero)
        for key in sorted(obs):
            h.update(np.asarray(obs[key]).tobytes())
        h.update(info["u_h"].tobytes() + env.data.qpos.tobytes() + env.data.qvel.tobytes())
        if trunc:
            break
    env.close()
    return h.hexdigest(), braked[0]


TWIST = ((0.0, 40.0, 0.0), (0.0, 0.0, 6.0), 0.5)
"""A hard twist: the brake's own chunks run."""
FAST_PUSH = ((19.5, 20.5, 38.4), (-0.3, -0.9, 3.6), 3.0)
"""A push that drives the arm into the speed reflex inside a physics chunk (Task 3, seed
20014)."""


def test_study_v2_rollouts_are_the_same_bytes_on_both_paths(path, monkeypatch):
    path(False)
    plain, braked = _study_rollout(2, 20003, 160, TWIST)
    assert braked > 5  # the brake's chunks ran, not only watched ones
    tripped, braked_too = _study_rollout(3, 20014, 45, FAST_PUSH)
    path(True)
    from strol_gym.envs.study import chunk, step_kernel

    codes: list[int] = []
    run = step_kernel.control_step

    def counting(*args):
        codes.append(run(*args))
        return codes[-1]

    monkeypatch.setattr(step_kernel, "control_step", counting)
    # the compiled control step (MuJoCo and numpy's BLAS called from the loop, the brake's own
    # steps and the reflexes inside it) ran, where it applies
    assert _study_rollout(2, 20003, 160, TWIST)[0] == plain
    assert len(codes) > 100 or chunk.functions() is None
    assert _study_rollout(3, 20014, 45, FAST_PUSH)[0] == tripped
    assert braked_too > 0 and (step_kernel.TRIP in codes or chunk.functions() is None)


def test_the_study_chunk_calls_numpys_own_blas(path):
    """With numpy's bundled OpenBLAS (the wheels), the compiled chunk finds it and its products
    are numpy's bits (``chunk._agrees``), under this process's ``OPENBLAS_CORETYPE``."""
    config = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
    if config.get("name") != "scipy-openblas":
        pytest.skip("numpy is not built with its bundled OpenBLAS")
    path(True)
    from strol_gym.envs.study import chunk

    fp = chunk.functions()
    assert fp is not None and chunk._agrees(fp, cases=5)


def test_the_compiled_step_reads_mujocos_contacts_as_the_binding_shows_them(path):
    """``step_kernel.touches`` reads ``mjData``'s contacts by address (``data_layout``): a
    sphere sunk in a plane touches it, and nothing else; no contacts, no touch."""
    import mujoco

    from strol_gym.envs.study import data_layout

    path(True)
    from strol_gym.envs.study import chunk, step_kernel

    found = chunk.functions()
    if found is None:
        pytest.skip("no compiled chunk on this platform (the plain path runs)")
    assert data_layout.contact_layout() is not None
    model = mujoco.MjModel.from_xml_string(data_layout._PROBE)
    data = mujoco.MjData(model)
    fp = np.array([*found, model._address, data._address], np.intp)
    floor, ball = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ("floor", "ball"))
    mujoco.mj_forward(model, data)
    assert data.ncon == 1 and {data.contact.geom1[0], data.contact.geom2[0]} == {floor, ball}
    assert step_kernel.touches(fp, ball, np.array([floor], np.int64))
    assert step_kernel.touches(fp, floor, np.array([7, ball], np.int64))
    assert not step_kernel.touches(fp, ball, np.array([ball + 5], np.int64))
    data.qpos[2] = 1.0  # lifted clear of the plane
    mujoco.mj_forward(model, data)
    assert data.ncon == 0 and not step_kernel.touches(fp, ball, np.array([floor], np.int64))


ADMITTANCE_CASES = (
    ((0.0,) * 12, (30.0, -12.0, 5.0, 0.4, -0.2, 1.5)),  # a push from rest
    ((1e-6, 0.0, -2e-6, 0.0, 1e-6, 0.0, 3e-6, 0.0, 0.0, -1e-6, 0.0, 2e-6), (0.0,) * 6),
    ((0.02, -0.01, 0.03, 0.1, -0.2, 0.3, 4.0, -3.0, 2.0, 5.0, -6.0, 7.0), (60.0, 0, 0, 0, 0, 3.0)),
)
"""The admittance's state before a control step and the person's wrench: a push from rest, a
state that settles to REST within the step with nobody pushing, a fast one the joints' speed
cap scales down."""


def test_the_compiled_admittance_terms_are_the_plain_bits(path):
    """``step_kernel.admitted`` writes ``_admitted``'s chunk terms and states, bit for bit."""
    path(True)
    from strol_gym.envs.study import step_kernel
    from strol_gym.envs.study.admittance import REST
    from strol_gym.envs.study.scene import HOLD
    from strol_gym.tasks.study import CONTROL_DT

    env = gym.make("StROL-Study-v2", task=3).unwrapped
    env.reset(seed=20100)
    env.step(np.zeros(env.action_space.shape, np.float32))
    fp = env._chunk_functions()
    if fp is None:
        pytest.skip("no compiled chunk on this platform (the plain path runs)")
    n, dt_i = len(env._var_still), HOLD * env._dt
    sp_r = np.ascontiguousarray(env._sp_R)
    settled = 0
    for state, wext in ADMITTANCE_CASES:
        start = REST if not any(state) else state
        env._adm = start
        chunks = env._admitted(sp_r, list(wext), dt_i)
        var, targets, states = (
            np.zeros((n, step_kernel.VAR)),
            np.empty((n, 3, 3)),
            np.zeros((n, 13)),
        )
        terms = (env._lam, env._jt_damp, env._dyn_inv)
        step_kernel.admitted(
            fp, env._adm_coef, np.array(start), start is REST, np.array(wext, float), *terms,
            sp_r, dt_i, CONTROL_DT, var, targets, states,
        )  # fmt: skip
        for i, (ox, oy, oz, target_r, feed, damp, adm) in enumerate(chunks):
            assert var[i, :6].tolist() == [
                ox,
                oy,
                oz,
                CONTROL_DT - i * dt_i,
                feed is not None,
                damp is not None,
            ]
            assert targets[i].tobytes() == target_r.tobytes()
            assert var[i, 6:12].tobytes() == (np.zeros(6) if feed is None else feed).tobytes()
            assert var[i, 12:].tolist() == (damp or [0.0] * 7)
            assert (states[i, 12] == 1.0) == (adm is REST) and states[i, :12].tolist() == list(adm)
            settled += adm is REST
    assert settled > 0  # the settling case reached REST
    fast = env._admit.step(ADMITTANCE_CASES[2][0], list(ADMITTANCE_CASES[2][1]))
    assert env._cap_speed(fast) != fast  # the fast case was scaled down
