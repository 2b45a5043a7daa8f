"""``strol-bench train``: train ĝ for StROL or e2e (Algorithm 1) for any Task, then check it on
held-out samples and save the weights with their sidecar (``strol_gym.learners.training`` does
the work; this is its command line, also ``python -m strol_gym.benchmarks.train``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from strol_gym.benchmarks.args import (
    TRAIN_CAPS,
    add_allow_large,
    check_size_caps,
    json_object,
    positive_int,
)
from strol_gym.learners.checkpoint import KINDS, SAFETENSORS, check_weights_path, save_checkpoint
from strol_gym.learners.network import BOUNDS
from strol_gym.learners.training import (
    ROBOT_ACTIONS,
    THETA_SAMPLING,
    TRAIN_PRIORS,
    TrainConfig,
    heldout_lyapunov,
    heldout_unrolled,
    train_correction,
    training_prior,
)
from strol_gym.tasks import make_task
from strol_gym.tasks.base import Task


def resolve_task(spec: str) -> Task:
    """A Task from a registered name ("robot"), an env id ("StROL-Robot-v0") or "module:attr"
    (``strol_gym.tasks.make_task``)."""
    return make_task(spec)


def add_train_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the training options to ``parser`` (``strol-bench train`` and this module)."""
    d = TrainConfig()
    a = parser.add_argument
    a(
        "--task",
        default="StROL-Robot-v0",
        help="a registered Task name (robot), an env id or module:attr",
    )
    a(
        "--kind",
        choices=KINDS,
        default=d.kind,
        help="strol: g~ = g + ĝ; e2e: g~ = ĝ (‖ĝ‖ ≤ ‖g‖); e2e-scratch: g~ = ĝ unbounded "
        "(the paper's e2e); strol-unrolled: g~ = g + ĝ(x, u_H, θ̂)",
    )
    a(
        "-K",
        "--unroll",
        type=int,
        default=d.unroll,
        metavar="K",
        help="loss = error after K unrolled updates (K = 1: eq. M7)",
    )
    a(
        "--out",
        default=None,
        help="weights path (.safetensors, or .pt for a torch state_dict); "
        "default <task>_<kind>.safetensors here",
    )
    a("--steps", type=int, default=d.steps)
    a("--batch", type=int, default=d.batch)
    a("--sigma", type=float, default=d.sigma, help="human noise, fraction of a_max")
    a("--bias", type=float, default=d.bias, help="human bias, fraction of a_max")
    a("--seed", type=int, default=d.seed, help="keep disjoint from evaluation seeds (0, 1, ...)")
    a("--human", default=d.human, help="a registered human's name or module:attr")
    a("--beta", type=float, default=d.beta, help="rationality β (humans that declare it)")
    a(
        "--human-kwargs",
        type=json_object("--human-kwargs"),
        default=None,
        help="JSON: the human's own kwargs",
    )
    a("--lr", type=float, default=d.lr)
    a("--lr-halve-every", type=int, default=d.lr_halve_every)
    a("--candidates", type=int, default=d.n_candidates, help="candidate actions for eq. M6")
    a("--theta-sampling", choices=THETA_SAMPLING, default=d.theta_sampling)
    a("--theta-jitter", type=float, default=d.theta_jitter)
    a("--robot-action", choices=ROBOT_ACTIONS, default=d.robot_action)
    a(
        "--bound",
        choices=BOUNDS,
        default=None,
        help="ĝ's bound (default: none for e2e-scratch, radial otherwise)",
    )
    a("--threads", type=positive_int("--threads"), default=d.threads)
    a(
        "--prior",
        choices=TRAIN_PRIORS,
        default=d.prior,
        help="θ* from the task's prior, or the hedged designer's prior (priors.HedgedPrior)",
    )
    a("--heldout", type=int, default=10_000, help="held-out samples for the eq. M5 check")
    a("--quiet", action="store_true", help="no progress bar")
    add_allow_large(parser)
    return parser


def run_train(args: argparse.Namespace) -> Path:
    """Train, check on held-out samples (seed + 1), save weights + sidecar; print a summary."""
    check_size_caps(args, TRAIN_CAPS)
    out = Path(args.out) if args.out is not None else None
    if out is not None:
        check_weights_path(out, "--out")  # before any work, not after it
    task = resolve_task(args.task)
    config = TrainConfig(
        kind=args.kind,
        steps=args.steps,
        batch=args.batch,
        sigma=args.sigma,
        bias=args.bias,
        seed=args.seed,
        human=args.human,
        beta=args.beta,
        lr=args.lr,
        lr_halve_every=args.lr_halve_every,
        n_candidates=args.candidates,
        theta_sampling=args.theta_sampling,
        theta_jitter=args.theta_jitter,
        robot_action=args.robot_action,
        bound=args.bound or ("none" if args.kind == "e2e-scratch" else TrainConfig.bound),
        threads=args.threads,
        unroll=args.unroll,
        prior=args.prior,
        human_kwargs=args.human_kwargs,
    )
    if args.heldout < 1:
        raise ValueError(f"heldout must be >= 1, got {args.heldout}")
    if out is None:
        short = task.task_id.split("-")[1].lower() if task.task_id.count("-") >= 2 else task.task_id
        out = Path(f"{short}_{config.kind}{SAFETENSORS}")
        check_weights_path(out, "--out")
    model, history = train_correction(task, config, quiet=args.quiet)
    check = heldout_lyapunov(task, model, config, seed=config.seed + 1, n=args.heldout)
    prior = training_prior(task, config)
    extra: dict[str, Any] = {
        "final_loss": float(history["loss"][-10:].mean()),
        "prior": {"name": getattr(prior, "name", type(prior).__name__), "repr": repr(prior)},
        "heldout_lyapunov": check,
    }
    if config.unroll > 1:
        extra["heldout_unrolled"] = heldout_unrolled(
            task, model, config, seed=config.seed + 1, n=min(args.heldout, 2000)
        )
    save_checkpoint(out, model, task, config.kind, config.to_dict(), extra)
    print(
        f"{task.task_id} {config.kind}: {config.steps} steps x {config.batch} in "
        f"{history['seconds']:.2f} s; final loss {extra['final_loss']:+.5f}\n"
        f"held-out eq. M5 term (seed {check['seed']}, n={check['samples']}): "
        f"trained {check['trained']:+.5f} vs Gradient (ĝ = 0) {check['gradient']:+.5f}\n"
        + (
            f"held-out error after K = {config.unroll} updates: trained "
            f"{extra['heldout_unrolled']['trained']:.4f} vs Gradient "
            f"{extra['heldout_unrolled']['gradient']:.4f}\n"
            if config.unroll > 1
            else ""
        )
        + f"saved {out} and {out.with_suffix('.json')}"
    )
    return out


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m strol_gym.benchmarks.train",
        description="Train StROL's correction term ĝ (Algorithm 1) for a task.",
    )
    args = add_train_arguments(parser).parse_args(argv)
    try:
        run_train(args)
    except (ValueError, OSError) as e:  # bad options or files: one line, exit status 2
        print(f"{parser.prog}: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
