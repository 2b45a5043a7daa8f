"""Offline training of ĝ (the paper's Algorithm 1, loss eq. M7), for any Task.

Each step draws a fresh batch, fully vectorised in numpy, and takes one Adam step in torch:

1. x ~ ``task.sample_start``; θ* ~ ``task.prior`` (the Task's prior: bimodal for the paper), or
   ``HedgedPrior`` over its modes with ``prior="hedged"``.
2. The robot's current estimate θ (Algorithm 1's "(x, θ, θ*) tuple"). Online, θ starts at the
   prior modes' mean θ0 and walks toward θ*, so by default (``theta_sampling="path"``)
   θ = θ0 + τ (θ* − θ0) + ν with τ ~ U[0, 1] and ν ~ N(0, ``theta_jitter``² I): the start, the
   points between it and θ*, and some off-path estimates. ``"prior-mean"`` uses θ = θ0 only;
   ``"prior"`` draws θ from the prior, independently of θ*.
3. u_R: zeros by default (the learning rule sees u_R only through x_R = f(x, 0, u_R));
   ``robot_action="uniform"`` draws it uniformly within ``task.robot_action_bound``.
4. The nominal human: u* from eq. M6 over ``n_candidates`` admissible candidates
   (``task.candidate_actions``, which always includes u = 0), or a Boltzmann-rational choice
   (``human="boltzmann"``); then u_H = u* + δ, δ ~ N(ε a_max, (σ a_max)²) (``humans.perturb``).
   Any other human (a registered name or "module:attr", see ``strol_gym.humans``) answers
   through the same batched interface (``humans.human_model`` with σ, ε, β, ``n_candidates``
   and ``human_kwargs``); a factory of single humans without a model is built per sample.
5. Loss (eq. M7, averaged): mean(α²‖g̃‖² − 2α e·g̃), e = θ* − θ, g̃ = g + ĝ (StROL) or ĝ (e2e).

With ``unroll`` = K > 1 the loss is the error after K updates instead of one (Algorithm 1
generalised): θ_{k+1} = θ_k + α g̃_k, the human re-choosing its correction (eq. M6) from the
current θ_k at each step and the state moving by f(x, u_H, u_R); the loss is
mean(‖θ* − θ_K‖² − ‖θ* − θ_0‖²), which for K = 1 is exactly eq. M7. Gradients flow through
θ_k (and, for ``kind="strol-unrolled"``, through ĝ's θ̂ input); the human's choice is data.

Adam (lr 1e-3, halved every 100 steps), batch 100, 500 steps for the Robot, as in the paper.
Runs are seeded (numpy Generator for data, torch seed for the initial weights) and deterministic
(torch deterministic algorithms and a fixed thread count during training).
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Collection, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from functools import partial
from typing import Any, TypeVar

import numpy as np
import torch

from strol_gym import checks
from strol_gym.humans import (
    HUMANS,
    check_fraction,
    check_human_kwargs,
    human_model,
)
from strol_gym.learners.checkpoint import (
    KINDS,
    THETA_KINDS,
    input_dim,
    model_input,
)
from strol_gym.learners.network import BOUNDS, DEFAULT_HIDDEN, CorrectionNet
from strol_gym.priors import HedgedPrior, Prior
from strol_gym.tasks.base import Task

THETA_SAMPLING = ("path", "prior-mean", "prior")
ROBOT_ACTIONS = ("zero", "uniform")
TRAIN_PRIORS = ("task", "hedged")
NORM_SAMPLES = 4096


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Everything that determines a training run (stored in the checkpoint sidecar)."""

    kind: str = "strol"
    steps: int = 500
    batch: int = 100
    sigma: float = 0.25
    bias: float = 0.0
    seed: int = 10_000
    human: str = "nominal"
    beta: float = 50.0
    lr: float = 1e-3
    lr_halve_every: int = 100
    n_candidates: int = 256
    theta_sampling: str = "path"
    theta_jitter: float = 0.1
    robot_action: str = "zero"
    hidden: tuple[int, ...] = DEFAULT_HIDDEN
    bound: str = "radial"
    threads: int = 1
    unroll: int = 1
    prior: str = "task"
    human_kwargs: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        def choice(name: str, options: Collection[str]) -> None:
            checks.name_in(name, getattr(self, name), options)

        def positive(name: str) -> None:
            checks.number(name, getattr(self, name), low=1, integer=True)

        choice("kind", KINDS)
        HUMANS.check_name(self.human)
        # the human's own kwargs: a dict of parameters it declares, never σ, ε or β
        check_human_kwargs(self.human, self.human_kwargs)
        if "n_candidates" in (self.human_kwargs or {}):  # training sets it: one place for it
            raise ValueError(
                "human_kwargs must not hold 'n_candidates' in training: it is TrainConfig's "
                "n_candidates (train --candidates)"
            )
        choice("theta_sampling", THETA_SAMPLING)
        choice("robot_action", ROBOT_ACTIONS)
        choice("bound", BOUNDS)
        if (self.kind == "e2e-scratch") != (self.bound == "none") and self.kind != "strol":
            raise ValueError(
                f"bound must be 'none' for kind 'e2e-scratch' (the paper's unbounded e2e) and "
                f"one of {BOUNDS[:-1]} for kind {self.kind!r}, got {self.bound!r}"
            )
        choice("prior", TRAIN_PRIORS)
        for name in ("steps", "batch", "lr_halve_every", "n_candidates", "threads"):
            positive(name)
        checks.number("unroll (K, the unrolled updates)", self.unroll, low=1, integer=True)
        check_fraction("sigma", self.sigma)
        check_fraction("bias", self.bias, allow_negative=True)
        for name in ("lr", "beta", "theta_jitter"):
            checks.number(name, getattr(self, name), low=0, low_open=name == "lr")
        checks.number("seed", self.seed, low=0, integer=True)
        object.__setattr__(self, "hidden", tuple(int(h) for h in self.hidden))

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["hidden"] = list(self.hidden)
        if d["human_kwargs"] is None:
            del d["human_kwargs"]
        return d


# ---------------------------------------------------------------------------------------- data
def training_prior(task: Task, config: TrainConfig) -> Prior:
    """Where training draws θ*: ``task.prior`` (the paper: the bimodal prior), or
    ``HedgedPrior`` over the task's modes (``prior="hedged"``, the designer's hedge)."""
    return task.prior if config.prior == "task" else HedgedPrior(task.prior_modes)


def sample_batch(task: Task, rng: np.random.Generator, n: int, config: TrainConfig) -> dict:
    """One synthetic dataset D of Algorithm 1: n tuples (x, θ, θ*, u_R, u_H) and g, z, e."""
    x = task.sample_start(rng, n)
    theta_star = training_prior(task, config).sample(rng, n)
    theta0 = np.asarray(task.prior_modes, dtype=np.float64).mean(axis=0)
    if config.theta_sampling == "path":
        tau = rng.uniform(0.0, 1.0, size=(n, 1))
        nu = config.theta_jitter * rng.standard_normal((n, task.dim))
        theta = theta0 + tau * (theta_star - theta0) + nu
    elif config.theta_sampling == "prior":
        theta = task.prior.sample(rng, n)
    else:
        theta = np.broadcast_to(theta0, (n, task.dim)).copy()
    if config.robot_action == "uniform":
        b = np.asarray(task.robot_action_bound, dtype=np.float64)
        u_r = rng.uniform(-1.0, 1.0, size=(n, task.action_dim)) * b
    else:
        u_r = np.zeros((n, task.action_dim))
    u_h = human_correction(task, config, rng, x, u_r, theta, theta_star)
    return {
        "x": x,
        "theta": theta,
        "theta_star": theta_star,
        "u_r": u_r,
        "u_h": u_h,
        "g": task.g(x, u_h, u_r),
        "z": model_input(task, config.kind, x, u_h, u_r, theta),
        "e": theta_star - theta,
    }


def human_correction(
    task: Task,
    config: TrainConfig,
    rng: np.random.Generator,
    x: np.ndarray,
    u_r: np.ndarray,
    theta: np.ndarray,
    theta_star: np.ndarray,
) -> np.ndarray:
    """The training human's u_H for a batch: its model (``humans.human_model``) asked once for
    the whole batch, with θ̂ = ``theta`` where the model teaches relative to it."""
    model = human_model(
        config.human,
        task,
        sigma=config.sigma,
        bias=config.bias,
        beta=config.beta,
        n_candidates=config.n_candidates,
        **(config.human_kwargs or {}),
    )
    return model.correct(x, u_r, theta_star, rng, theta_hat=theta)


def lyapunov_term(alpha: float, e: np.ndarray, g_tilde: np.ndarray) -> np.ndarray:
    """The left side of eq. M5 per sample: α²‖g̃‖² − 2α e·g̃ (< 0 means the error shrinks)."""
    return alpha**2 * np.sum(g_tilde * g_tilde, axis=-1) - 2 * alpha * np.sum(e * g_tilde, axis=-1)


REPLACING_KINDS = ("e2e", "e2e-scratch")
"""Kinds whose rule is ĝ alone (g̃ = ĝ); every other kind adds ĝ to g."""


Batch = TypeVar("Batch", torch.Tensor, np.ndarray)


def modified_rule(kind: str, g: Batch, g_hat: Batch) -> Batch:
    """g̃ for a kind: ĝ (e2e, e2e-scratch) or g + ĝ (StROL and strol-unrolled, λ = 1)."""
    return g_hat if kind in REPLACING_KINDS else g + g_hat


INDUCTOR_CACHE = "TORCHINDUCTOR_CACHE_DIR"
"""torch's compiler cache folder (default ``$TMPDIR/torchinductor_<user>``)."""


def _deterministic_kernels(on: bool) -> None:
    """``torch.use_deterministic_algorithms(on)`` without the folder it leaves behind: its first
    call imports torch's compiler, whose import makes its cache folder although nothing is
    compiled. That import makes it in a temporary folder, removed at once; a cache folder the
    caller chose (``TORCHINDUCTOR_CACHE_DIR``), or a compiler already imported, is left alone."""
    if INDUCTOR_CACHE in os.environ or "torch._dynamo" in sys.modules:
        torch.use_deterministic_algorithms(on)
        return
    aside = tempfile.mkdtemp(prefix="strol-gym-torch-")
    os.environ[INDUCTOR_CACHE] = aside
    try:
        torch.use_deterministic_algorithms(on)
    finally:  # torch reads the variable on use: a later torch.compile gets its default again
        os.environ.pop(INDUCTOR_CACHE, None)
        shutil.rmtree(aside, ignore_errors=True)


@contextmanager
def torch_determinism(seed: int, threads: int) -> Iterator[None]:
    """Seed torch, fix the thread count and use deterministic kernels; restore on exit."""
    prev_threads = torch.get_num_threads()
    prev_det = torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(threads)
    _deterministic_kernels(True)
    try:
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            yield
    finally:
        torch.set_num_threads(prev_threads)
        torch.use_deterministic_algorithms(prev_det)


def _tensors(batch: dict, keys: Sequence[str]) -> list[torch.Tensor]:
    return [torch.as_tensor(batch[k], dtype=torch.float32) for k in keys]


# ---------------------------------------------------------------------------------------- train
def _train_step(
    model: CorrectionNet, opt: torch.optim.Optimizer, kind: str, alpha: float, batch: dict
) -> float:
    """One Adam step on eq. M7 (averaged over the batch); returns the loss."""
    z, g, e = _tensors(batch, ("z", "g", "e"))
    g_tilde = modified_rule(kind, g, model(z, g))
    loss = (alpha**2 * (g_tilde * g_tilde).sum(-1) - 2 * alpha * (e * g_tilde).sum(-1)).mean()
    return _adam_step(opt, loss)


def _adam_step(opt: torch.optim.Optimizer, loss: torch.Tensor) -> float:
    """Backpropagate ``loss``, take one optimiser step; returns the loss as a float."""
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()
    return float(loss.item())


def unroll(
    task: Task,
    model: CorrectionNet | None,
    config: TrainConfig,
    batch: dict,
    rng: np.random.Generator,
) -> tuple[torch.Tensor, torch.Tensor]:
    """K = ``config.unroll`` updates from ``batch`` (its u_H is the first correction; later
    ones come from ``human_correction`` at the current θ_k). Returns (θ_0, θ_K) as float32
    tensors; θ_K carries gradients into ``model``. ``model=None`` means ĝ = 0 (Gradient)."""
    alpha = float(task.alpha)
    x, u_r, u_h, theta_star = batch["x"], batch["u_r"], batch["u_h"], batch["theta_star"]
    theta0 = torch.as_tensor(batch["theta"], dtype=torch.float32)
    theta = theta0
    for k in range(config.unroll):
        if k > 0:
            th = theta.detach().double().numpy()
            u_h = human_correction(task, config, rng, x, u_r, th, theta_star)
        g = torch.as_tensor(task.g(x, u_h, u_r), dtype=torch.float32)
        if model is None:
            g_tilde = g
        else:
            z = torch.as_tensor(task.network_input(x, u_h, u_r), dtype=torch.float32)
            if config.kind in THETA_KINDS:  # as checkpoint.model_input, with θ_k differentiable
                z = torch.cat([z, theta], dim=-1)
            g_tilde = modified_rule(config.kind, g, model(z, g))
        theta = theta + alpha * g_tilde
        x = task.dynamics(x, u_h, u_r)
    return theta0, theta


def unrolled_loss(theta_star: np.ndarray, theta0: torch.Tensor, theta: torch.Tensor):
    """mean(‖θ* − θ_K‖² − ‖θ* − θ_0‖²): eq. M7 for K = 1, the K-step error otherwise."""
    star = torch.as_tensor(theta_star, dtype=torch.float32)
    return (((star - theta) ** 2).sum(-1) - ((star - theta0) ** 2).sum(-1)).mean()


def _unrolled_step(
    model: CorrectionNet,
    opt: torch.optim.Optimizer,
    task: Task,
    config: TrainConfig,
    rng: np.random.Generator,
) -> float:
    """One Adam step on the K-step loss; the data depend on the model, so they are drawn here."""
    batch = sample_batch(task, rng, config.batch, config)
    theta0, theta = unroll(task, model, config, batch, rng)
    return _adam_step(opt, unrolled_loss(batch["theta_star"], theta0, theta))


def _losses(
    model: CorrectionNet,
    opt: torch.optim.Optimizer,
    task: Task,
    config: TrainConfig,
    rng: np.random.Generator,
) -> Iterator[float]:
    """Take ``config.steps`` Adam steps, yielding each step's loss."""
    if config.unroll > 1:  # each batch depends on the model: no prefetching
        for _ in range(config.steps):
            yield _unrolled_step(model, opt, task, config, rng)
        return
    # Draw the next batch in a worker thread while torch trains on this one. One worker uses
    # the Generator in order, so the data are the same as drawn serially.
    alpha = float(task.alpha)
    with ThreadPoolExecutor(max_workers=1) as pool:
        draw = partial(sample_batch, task, rng, config.batch, config)
        pending = pool.submit(draw)
        for step in range(config.steps):
            batch = pending.result()
            if step + 1 < config.steps:
                pending = pool.submit(draw)
            yield _train_step(model, opt, config.kind, alpha, batch)


def _progress_bar(steps: range, desc: str) -> Any:
    """tqdm's bar over ``steps``, or None without tqdm (the [bench] extra brings it; the core
    install trains the same, silently)."""
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(steps, desc=desc, leave=False)


def train_correction(
    task: Task, config: TrainConfig | None = None, *, quiet: bool = False, **overrides: Any
) -> tuple[CorrectionNet, dict[str, Any]]:
    """Train ĝ for ``task``. Keyword overrides set ``TrainConfig`` fields (kind, steps, batch,
    sigma, bias, seed, human, ...). Returns (model, history) with history["loss"] per step,
    history["seconds"] (wall time) and history["config"]."""
    if not isinstance(task, Task):
        raise ValueError(f"task must be a strol_gym Task, got {type(task).__name__}")
    config = dataclasses.replace(config or TrainConfig(), **overrides)
    start = time.perf_counter()
    rng = np.random.default_rng(config.seed)
    norm = sample_batch(task, np.random.default_rng([config.seed, 1]), NORM_SAMPLES, config)
    losses = np.empty(config.steps)
    with torch_determinism(config.seed, config.threads):
        model = CorrectionNet(input_dim(task, config.kind), task.dim, config.hidden, config.bound)
        z = torch.as_tensor(norm["z"], dtype=torch.float32)
        model.in_mean.copy_(z.mean(0))
        model.in_std.copy_(z.std(0).clamp_min(1e-6))
        opt = torch.optim.Adam(model.parameters(), lr=config.lr)
        sched = torch.optim.lr_scheduler.StepLR(opt, step_size=config.lr_halve_every, gamma=0.5)
        steps = range(config.steps)
        bar = None if quiet else _progress_bar(steps, f"train {config.kind}")
        for step, loss in zip(
            steps if bar is None else bar, _losses(model, opt, task, config, rng), strict=False
        ):
            losses[step] = loss
            sched.step()
            if bar is not None and (step % 10 == 0 or step == config.steps - 1):
                bar.set_postfix(loss=f"{loss:+.4f}", refresh=False)
        if bar is not None:
            bar.close()
    model.eval()
    history = {
        "loss": losses,
        "seconds": time.perf_counter() - start,
        "config": config.to_dict(),
    }
    return model, history


def heldout_lyapunov(
    task: Task,
    model: CorrectionNet,
    config: TrainConfig,
    seed: int,
    n: int = 10_000,
) -> dict[str, float]:
    """Mean eq. M5 term on fresh samples from the training distribution (another seed):
    with the trained ĝ (g̃ = g + ĝ or ĝ) and with ĝ = 0 in StROL, i.e. Gradient (g̃ = g)."""
    batch = sample_batch(task, np.random.default_rng(seed), n, config)
    with torch.no_grad():
        g_hat = model(
            torch.as_tensor(batch["z"], dtype=torch.float32),
            torch.as_tensor(batch["g"], dtype=torch.float64),
        ).numpy()
    g_tilde = modified_rule(config.kind, batch["g"], g_hat)
    return {
        "trained": float(lyapunov_term(task.alpha, batch["e"], g_tilde).mean()),
        "gradient": float(lyapunov_term(task.alpha, batch["e"], batch["g"]).mean()),
        "seed": int(seed),
        "samples": int(n),
    }


def heldout_unrolled(
    task: Task, model: CorrectionNet, config: TrainConfig, seed: int, n: int = 10_000
) -> dict[str, float]:
    """Mean error ‖θ* − θ_K‖ after K = ``config.unroll`` updates on fresh samples (another
    seed), with the trained ĝ and with ĝ = 0 (Gradient); both see the same first draws."""
    out: dict[str, float] = {}
    for label, net in (("trained", model), ("gradient", None)):
        rng = np.random.default_rng(seed)
        batch = sample_batch(task, rng, n, config)
        with torch.no_grad():
            _, theta = unroll(task, net, config, batch, rng)
        err = np.linalg.norm(batch["theta_star"] - theta.double().numpy(), axis=-1)
        out[label] = float(err.mean())
    return {**out, "unroll": int(config.unroll), "seed": int(seed), "samples": int(n)}
