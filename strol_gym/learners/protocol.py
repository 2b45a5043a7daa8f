"""The interface every online reward learner implements, and a base class for rules of eq. P2.

A learner holds a point estimate θ̂ of the human's reward weights and moves it after each human
correction: θ̂ ← θ̂ + α·G(x, u_H, u_R). Learners work on one interaction (1-D arrays) or on a
batch of independent interactions (arrays with a leading batch axis) alike, so a benchmark can
run many simulated humans in one call.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from strol_gym import checks
from strol_gym.priors import check_theta_range
from strol_gym.tasks.base import Task


@runtime_checkable
class OnlineRewardLearner(Protocol):
    """What the wrapper and the benchmark need from a learner.

    ``theta`` is (d,) for a single interaction or (B, d) for a batch. ``reset(None)`` starts from
    the mean of the task's bimodal prior modes (``task.prior_modes.mean(0)``), the robot's θ̂0 in
    the paper. ``state_dict`` / ``load_state_dict`` round-trip the learner exactly.
    """

    task: Task
    theta: np.ndarray

    def reset(self, theta0: np.ndarray | None = None) -> np.ndarray:
        """Start a new interaction from ``theta0`` (default: the prior modes' mean)."""
        ...

    def update(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None = None) -> np.ndarray:
        """Learn from one correction: state x, human action u_H, robot action u_R. Returns θ̂."""
        ...

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to restore the learner (numpy arrays, torch tensors and plain
        values), for ``load_state_dict`` in this or another process (it pickles). It is not a
        torch checkpoint: ``torch.load(weights_only=True)`` refuses the numpy arrays in it;
        ĝ weights travel as safetensors files (``learners.checkpoint``)."""
        ...

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a learner from ``state_dict()``."""
        ...


class LearnerFailed(RuntimeError):
    """A learner raised while a benchmark or a replay ran it. The message names the learner and
    where (run seed, episode, correction), so the command line reports one line, not a traceback.
    """

    @classmethod
    def of(cls, learner: str, where: str, error: BaseException) -> LearnerFailed:
        """The error for ``learner`` raising ``error`` at ``where``, on one line."""
        said = " ".join(str(error).split())
        return cls(f"learner {learner!r} failed {where}: {type(error).__name__}: {said}")


def check_state(state: Any, name: str) -> dict[str, Any]:
    """``state`` for ``load_state_dict``: TypeError unless it is a dict (``None`` included)."""
    if not isinstance(state, dict):
        raise TypeError(
            f"{name}.load_state_dict needs the dict from state_dict(), got {type(state).__name__}"
        )
    return state


def _as_float_array(name: str, value: np.ndarray, width: int) -> np.ndarray:
    arr = checks.array(name, value, finite=False)
    if arr.ndim not in (1, 2) or arr.shape[-1] != width or (arr.ndim == 2 and len(arr) < 1):
        raise ValueError(
            f"{name} must have shape ({width},) or (B, {width}) with B >= 1, got {arr.shape}"
        )
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr


def as_theta(name: str, value: np.ndarray, dim: int) -> np.ndarray:
    """A learner's start θ̂0 or a restored state's θ̂, (d,) or (B, d), within ±``MAX_THETA``
    as a prior's and θ*'s are: a larger one (1e308) only makes the next update overflow, and
    that update's error would blame its inputs."""
    arr = _as_float_array(name, value, dim)
    check_theta_range(name, arr)
    return arr


def batch_inputs(
    task: Task, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """Validate one update's inputs and broadcast them to 2-D batches of one length B.

    Returns (x (B, s), u_h (B, a), u_r (B, a), theta (B, d), single), where ``single`` says
    that every input was 1-D (the learner then returns a (d,) estimate). u_r None means 0.
    Raises ValueError naming the argument for a wrong shape, NaN / inf or mismatched batches.
    """
    x = _as_float_array("x", x, task.state_dim)
    u_h = _as_float_array("u_h", u_h, task.action_dim)
    u_r = np.zeros(task.action_dim) if u_r is None else u_r
    u_r = _as_float_array("u_r", u_r, task.action_dim)
    theta = np.asarray(theta, dtype=np.float64)
    single = x.ndim == 1 and u_h.ndim == 1 and u_r.ndim == 1 and theta.ndim == 1
    arrays = [np.atleast_2d(a) for a in (x, u_h, u_r, theta)]
    try:
        b = np.broadcast_shapes(*(a.shape[:1] for a in arrays))[0]
    except ValueError:
        lens = [a.shape[0] for a in arrays]
        raise ValueError(
            f"batch sizes of x, u_h, u_r and theta disagree: {lens} (each must be B or 1)"
        ) from None
    x2, uh2, ur2, th2 = (np.broadcast_to(a, (b, a.shape[1])) for a in arrays)
    return x2, uh2, ur2, th2, single


def checked_theta(theta: np.ndarray) -> np.ndarray:
    """An update's new θ̂, or ValueError if it is not finite (inputs so large that the rule
    overflows); callers assign θ̂ only after this returns, so a refused update changes nothing."""
    if not np.isfinite(theta).all():
        raise ValueError(
            "the update gives a non-finite θ̂ (x, u_h or u_r too large for the learning rule); "
            "θ̂ is left unchanged"
        )
    return theta


class LinearRuleLearner:
    """Base for learners of the form θ̂ ← θ̂ + α·G, with G computed by ``direction``.

    Subclasses implement ``direction(x, u_h, u_r, theta)`` on 2-D batches of equal length and
    return G with shape (B, d). This class handles validation, batching, and state.
    """

    name: str = "rule"

    def __init__(self, task: Task) -> None:
        if not isinstance(task, Task):
            raise ValueError(f"task must be a strol_gym Task, got {type(task).__name__}")
        self.task = task
        self.theta = np.asarray(task.prior_modes, dtype=np.float64).mean(axis=0)

    # ------------------------------------------------------------------ interface
    def reset(self, theta0: np.ndarray | None = None) -> np.ndarray:
        if theta0 is None:
            theta0 = np.asarray(self.task.prior_modes, dtype=np.float64).mean(axis=0)
        self.theta = as_theta("theta0", theta0, self.task.dim).copy()
        return self.theta.copy()

    def update(self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray | None = None) -> np.ndarray:
        x2, uh2, ur2, th2, single = batch_inputs(self.task, x, u_h, u_r, self.theta)
        with np.errstate(over="ignore", invalid="ignore"):
            theta = th2 + self.task.alpha * self.direction(x2, uh2, ur2, th2)
        theta = checked_theta(theta)
        self.theta = theta[0] if single else theta
        return self.theta.copy()

    def direction(
        self, x: np.ndarray, u_h: np.ndarray, u_r: np.ndarray, theta: np.ndarray
    ) -> np.ndarray:
        """G for each sample, (B, d). Subclasses override."""
        raise NotImplementedError

    def config(self) -> dict[str, Any]:
        """The constructor arguments besides the task (JSON-ready)."""
        return {}

    def state_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "task_id": self.task.task_id,
            "config": self.config(),
            "theta": self.theta.copy(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.check_identity(state)
        if "theta" not in state:
            raise ValueError(f"state lacks {self.name}'s estimate: missing key 'theta'")
        try:
            theta = np.asarray(state["theta"], dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"state['theta'] must be {self.task.dim} numbers ({e})") from None
        self.theta = as_theta("state['theta']", theta, self.task.dim).copy()

    def check_identity(self, state: Any) -> None:
        """ValueError unless ``state`` is this learner's kind, Task and config: checked first,
        so that a state of another size is named as such, not by its arrays' shapes."""
        check_state(state, self.name)
        if state.get("name") != self.name:
            raise ValueError(f"state is for learner {state.get('name')!r}, not {self.name!r}")
        if state.get("task_id") != self.task.task_id:
            raise ValueError(
                f"state is for task {state.get('task_id')!r}, this learner's task is "
                f"{self.task.task_id!r}"
            )
        if state.get("config") != self.config():
            raise ValueError(
                f"state config {state.get('config')} differs from this learner's {self.config()}"
            )

    def __repr__(self) -> str:
        cfg = ", ".join(f"{k}={v!r}" for k, v in self.config().items())
        return f"{type(self).__name__}(task={self.task.task_id}{', ' if cfg else ''}{cfg})"
