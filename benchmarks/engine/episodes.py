"""The episode loop: a block of (learner, run seed) episodes in lockstep, and their records.

Every step the robot acts for each learner's own θ̂ (one policy call for the whole block); a
record holds the run's metrics, defined once in ``strol_gym.metrics``, the one table the
wrapper reads as well. Regret is scored for the whole block by one batched ``Task.regret``
call (``score_regret``), a speed feature of the runner; the wrapper scores one episode at a
time with the same definition (``episode_regret``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, cast

import numpy as np

from strol_gym.benchmarks.engine.record import REGRET_INPUTS, RunRecord
from strol_gym.envs.study import metrics as study_authors
from strol_gym.learners.protocol import LearnerFailed
from strol_gym.metrics import cos_error, episode_regret, error, info_metrics

CORRECTION_METRICS: dict[str, Callable[[dict], float]] = {
    "correction_time_authors": study_authors.correction_time,
}
"""Per-correction values summed over an episode, from the ``correction_record`` an env puts in
``info`` when a correction ends (the study env does); recorded for envs that report
``correction_time``."""


def _state(obs: Any) -> np.ndarray:
    return np.asarray(obs["state"] if isinstance(obs, dict) else obs, dtype=np.float64)


def score_regret(task: Any, records: list[RunRecord]) -> None:
    """Every record's regret in one batched call: the unit's planning is batched, and θ*'s plan
    from a run's x0, shared by all learners on that seed, is made once (``Task.regret``)."""
    if not records:
        return
    for record, regret in zip(records, episode_regret(task, *regret_inputs(records)), strict=True):
        record["regret"] = regret


def regret_inputs(records: Sequence[RunRecord]) -> list[np.ndarray]:
    """The ``REGRET_INPUTS`` columns of ``records``, one float64 array each."""
    return [np.asarray([r[k] for r in records], dtype=np.float64) for k in REGRET_INPUTS]


def run_block(
    runs: Sequence[tuple[str, int, Any]],
    steps: int,
    env: str,
    cond: str,
    policy: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> list[RunRecord]:
    """Lockstep episodes of ``runs`` = (learner name, run seed, its wrapped env): one policy
    call per step for all of them; a record per run, in the order given."""
    wrapped = [w for _, _, w in runs]
    seeds = [s for _, s, _ in runs]
    task = wrapped[0].unwrapped.task
    bound = np.asarray(task.robot_action_bound, dtype=np.float64)
    b = len(seeds)

    def failed(i: int, e: Exception) -> LearnerFailed:
        where = f"in run seed {seeds[i]} ({env}, condition {cond})"
        return LearnerFailed.of(str(runs[i][0]), where, e)

    obs = []
    for i, (w, s) in enumerate(zip(wrapped, seeds, strict=True)):
        try:
            obs.append(w.reset(seed=int(s))[0])
        except Exception as e:  # a user's learner may raise anything: name it and the run
            raise failed(i, e) from None
    x0 = [_state(o) for o in obs]
    thetas = [[np.array(w.learner.theta, dtype=np.float64)] for w in wrapped]
    alive = np.ones(b, dtype=bool)
    last_info: list[dict] = [{} for _ in range(b)]
    first_corr: list[Any] = [None] * b
    per_corr = [dict.fromkeys(CORRECTION_METRICS, 0.0) for _ in range(b)]
    terminated = np.zeros(b, dtype=bool)
    n_steps = np.zeros(b, dtype=int)
    for _ in range(steps):
        idx = np.flatnonzero(alive)
        if len(idx) == 0:
            break
        x = np.stack([_state(obs[i]) for i in idx])
        th = np.stack([np.asarray(wrapped[i].learner.theta, dtype=np.float64) for i in idx])
        u = policy(x, th)
        action = np.clip(u / bound, -1.0, 1.0).astype(np.float32)
        for j, i in enumerate(idx.tolist()):
            try:
                o, _, term, trunc, info = wrapped[i].step(action[j])
            except Exception as e:
                raise failed(i, e) from None
            obs[i], last_info[i] = o, info
            n_steps[i] += 1
            thetas[i].append(np.array(wrapped[i].learner.theta, dtype=np.float64))
            if first_corr[i] is None and info.get("is_correction", False):
                first_corr[i] = np.asarray(info["correction"], dtype=np.float64).tolist()
            if "correction_record" in info:
                for name, fn in CORRECTION_METRICS.items():
                    per_corr[i][name] += fn(info["correction_record"])
            if term or trunc:
                alive[i] = False
                terminated[i] = bool(term)
    records: list[RunRecord] = []
    for i, seed in enumerate(seeds):
        info = last_info[i]
        star = np.asarray(info["theta_star"], dtype=np.float64)
        errs = [error(star, t) for t in thetas[i]]
        coss = [cos_error(star, t) for t in thetas[i]]
        record: RunRecord = {
            "env": env,
            "condition": cond,
            "learner": runs[i][0],
            "seed": int(seed),
            "error": errs[-1],
            "cos_error": coss[-1],
            "regret": float("nan"),  # scored for the whole unit at once: score_regret
            "errors": errs,
            "cos_errors": coss,
            "steps": int(n_steps[i]),
            "terminated": bool(terminated[i]),
            "theta_star": star.tolist(),
            "theta_hat": thetas[i][-1].tolist(),
            "x0": x0[i].tolist(),
            "first_correction": first_corr[i],
        }
        extra = {k: float(info[k]) for k in info_metrics() if k in info}  # the env's own totals
        extra |= per_corr[i] if "correction_time" in info else {}
        records.append(cast(RunRecord, {**record, **extra}))  # a user's metric is not a field above
    return records
