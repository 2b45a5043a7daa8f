"""``strol-bench export LOG DATASET_ID``: a session log as a Minari dataset, and back.

Minari is the Gymnasium ecosystem's format for recorded episodes (``minari.load_dataset``).
One Minari step is one correction: the observation is what the learner saw (``state`` = x,
``correction`` = u_H, ``theta_hat`` = θ̂ before the update, ``phi`` = φ(x)), the action is the
robot's u_R scaled to the env's action space (u_R / ``robot_action_bound``), and the last
observation carries the final θ̂; the spaces are the env's own. Where the env observes more than
a log keeps (the study envs' wrench), the dataset keeps its own spaces (no φ, the action u_R).
Observations are float32 (Minari's spaces), so the exact float64 x, u_H, u_R, θ̂ and θ* travel
in the episode's infos, and replaying a dataset gives the θ̂ of replaying the log, to the bit.
The log's header rides in the dataset's metadata and is checked like a log's, and the folder's
metadata passes :mod:`dataset_gate` before Minari reads it: reading a dataset never runs code.
The dataset's ``env_spec`` (when the session names only registered pieces) is the logged env
wrapped in the logged learner, so Minari's ``recover_environment()`` rebuilds it;
``algorithm_name`` is the learner's name.

Datasets are written under ``MINARI_DATASETS_PATH`` (default ``~/.minari/datasets``). Needs the
``[data]`` extra (``pip install ".[data]"``).
"""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from strol_gym.benchmarks.sessions.dataset_gate import (
    METADATA,
    DatasetRefused,
    check_metadata,
    dataset_path,
    wrappers,
)
from strol_gym.wrappers.session_log import (
    Episode,
    Session,
    SessionLogError,
    check_header,
    read_session,
    session_task,
)

HEADER_KEY = "strol_session_header"


def _minari() -> Any:
    try:
        import minari
    except ImportError:
        raise ValueError(
            'Minari is not installed: pip install "strol-gym[data]" (or ".[data]" in a clone)'
        ) from None
    return minari


def _spaces(dims: dict[str, int]) -> tuple[spaces.Dict, spaces.Box]:
    box = lambda n: spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)  # noqa: E731
    obs = spaces.Dict(
        {"state": box(dims["s"]), "correction": box(dims["a"]), "theta_hat": box(dims["d"])}
    )
    return obs, box(dims["a"])


def _env_spaces(spec: Any, dims: dict[str, int]) -> tuple[Any, spaces.Space, spaces.Space, bool]:
    """``spec`` (None if no env can be made from it) and the spaces of the env it makes when
    the dataset fills them (its observation is exactly state, correction, θ̂ and φ; its action
    the scaled u_R), and True; else the dataset's own spaces (state, correction, θ̂; u_R) and
    False (e.g. the study envs' wrench, which a session log does not keep per step)."""
    if spec is None:
        return (None, *_spaces(dims), False)
    import gymnasium as gym

    try:
        env = gym.make(spec)
    except Exception:  # logged kwargs this version cannot make an env from: no env_spec
        return (None, *_spaces(dims), False)
    try:
        obs, act = env.observation_space, env.action_space
    finally:
        env.close()
    want = {"state": dims["s"], "correction": dims["a"], "theta_hat": dims["d"], "phi": dims["d"]}
    ok = (
        isinstance(obs, spaces.Dict)
        and isinstance(act, spaces.Box)
        and {k: v.shape for k, v in obs.spaces.items()} == {k: (n,) for k, n in want.items()}
        and act.shape == (dims["a"],)
    )
    return (spec, obs, act, True) if ok else (spec, *_spaces(dims), False)


FLOAT32_MAX = float(np.finfo(np.float32).max)
"""The largest number a dataset's float32 observations and actions hold (larger: inf)."""


def _episode_buffer(ep: Episode, dims: dict[str, int], seed: int | None, task: Any = None) -> Any:
    """One episode as Minari's buffer. With ``task`` (the env's own spaces), the observation
    adds φ(x) and the action is u_R scaled to the env's action space (u_R / robot_action_bound)."""
    from minari.data_collector import EpisodeBuffer

    n, nan = len(ep.corrections), np.nan
    x = np.array([c["x"] for c in ep.corrections] + [np.zeros(dims["s"])]).reshape(n + 1, -1)
    u_h = np.array([c["u_h"] for c in ep.corrections] + [np.zeros(dims["a"])]).reshape(n + 1, -1)
    u_r = np.array([c["u_r"] for c in ep.corrections] + [np.zeros(dims["a"])]).reshape(n + 1, -1)
    thetas = [ep.theta_hat0] + [
        c["theta_hat_after"] if c["theta_hat_after"] is not None else np.full(dims["d"], nan)
        for c in ep.corrections
    ]
    theta = np.array(thetas).reshape(n + 1, -1)
    if n:
        x[n] = x[n - 1]  # the last observation: where the last correction began, final θ̂
    star = np.full(dims["d"], nan) if ep.theta_star is None else ep.theta_star
    ctime = [nan if c["correction_time"] is None else c["correction_time"] for c in ep.corrections]
    for key, values in (("x", x), ("u_h", u_h), ("u_r", u_r), ("theta_hat", theta)):
        finite = values[np.isfinite(values)]
        if finite.size and np.abs(finite).max() > FLOAT32_MAX:  # float32 would store it as inf
            raise ValueError(
                f"episode with seed {seed}: {key} holds {np.abs(finite).max():.3g}, beyond the "
                f"float32 range (±{FLOAT32_MAX:.3g}) of the dataset's observations and actions"
            )
    observations = {
        "state": x.astype(np.float32),
        "correction": u_h.astype(np.float32),
        "theta_hat": theta.astype(np.float32),
    }
    actions = u_r[:n]
    if task is not None:
        observations["phi"] = np.asarray(task.features(x), dtype=np.float32).reshape(n + 1, -1)
        actions = actions / np.asarray(task.robot_action_bound, dtype=np.float64)
    return EpisodeBuffer(
        seed=seed,
        observations=observations,
        actions=actions.astype(np.float32),
        rewards=[0.0] * n,  # the person's reward is hidden (θ* in the infos is what they taught)
        terminations=[False] * n,
        truncations=[False] * (n - 1) + [True] if n else [],
        infos={
            "x": x,
            "u_h": u_h,
            "u_r": u_r,
            "theta_hat": theta,
            "theta_star": np.tile(star, (n + 1, 1)),
            "is_correction": np.arange(n + 1) < n,
            "correction_time": np.array([*ctime, nan]),
        },
    )


SAME_SETTING = ("env_id", "env_kwargs", "task", "learner", "learner_kwargs")
"""Header fields every log of one dataset shares (one env, Task and learner)."""


def export_session(log: str | Path | list[str | Path], dataset_id: str) -> Any:
    """Write session log ``log`` (or several logs of one setting: the same env, Task and
    learner, :data:`SAME_SETTING`, e.g. a study's people) as Minari dataset ``dataset_id``,
    their episodes in order; the MinariDataset. The first log's header is the dataset's.

    The id is checked before anything is created (:func:`dataset_gate.dataset_path`), and a
    failed export removes the folder it began."""
    folder = new_dataset_path(dataset_id)
    minari = _minari()
    logs = log if isinstance(log, list) else [log]
    if not logs:
        raise ValueError(f"dataset_id {dataset_id!r}: no session log to export")
    sessions = [read_session(one) for one in logs]
    session = sessions[0]
    for other in sessions[1:]:
        differ = [k for k in SAME_SETTING if other.header.get(k) != session.header.get(k)]
        if differ:
            raise ValueError(
                f"{other.path}: its {', '.join(differ)} differ from {session.path}'s; one "
                "dataset holds sessions of one env, Task and learner"
            )
    _, dims = check_header(f"{session.path}:1", session.header)
    task = session_task(session)  # a registered Task (or a --plugin's): never imported here
    spec, obs_space, act_space, own = _env_spaces(env_spec(session.header, dataset_id), dims)
    buffers = [
        _episode_buffer(ep, dims, ep.seed, task if own else None)
        for one in sessions
        for ep in one.episodes
    ]
    names = ", ".join(one.path.name for one in sessions[:3]) + (
        ", ..." if len(sessions) > 3 else ""
    )
    # Minari nags for provenance a session log does not have (author, code permalink)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=UserWarning, module=r"minari\.")
        try:
            dataset = minari.create_dataset_from_buffers(
                dataset_id,
                buffers,
                env=spec,
                observation_space=obs_space,
                action_space=act_space,
                algorithm_name=str(session.header.get("learner")),
                description=f"strol-gym session(s) {names}: corrections on "
                f"{session.header['env_id']}, task {session.header['task']}",
            )
        except BaseException as e:
            shutil.rmtree(folder, ignore_errors=True)  # it did not exist: nothing of ours is left
            if isinstance(e, ValueError):
                raise ValueError(f"dataset_id {dataset_id!r}: {e}") from None
            raise
    dataset.storage.update_metadata({HEADER_KEY: json.dumps(session.header)})
    return dataset


def env_spec(header: dict[str, Any], dataset_id: str) -> Any:
    """The env a session ran in, as an ``EnvSpec`` Minari's ``recover_environment()`` makes:
    the registered env id with the logged kwargs, wrapped in the logged learner. None (no
    env_spec) unless it passes the gate readers apply, i.e. names only our env, our wrapper
    and registered pieces (a plugin's ``module:attr`` learner or Task cannot be recovered)."""
    import dataclasses

    import gymnasium as gym
    from gymnasium.envs.registration import WrapperSpec

    from strol_gym.benchmarks.sessions.dataset_gate import check_env_spec, registered_envs

    if header.get("env_id") not in registered_envs():
        return None
    spec = dataclasses.replace(gym.spec(header["env_id"]), kwargs=dict(header["env_kwargs"]))
    if header.get("learner") is not None:
        kwargs = {"learner": header["learner"], "learner_kwargs": header["learner_kwargs"] or None}
        name, entry = next(iter(wrappers().items()))
        spec.additional_wrappers = (WrapperSpec(name, entry, kwargs),)
    try:
        check_env_spec(f"dataset {dataset_id}: env_spec", spec.to_json())
    except (DatasetRefused, ValueError):
        return None
    return spec


def new_dataset_path(dataset_id: str) -> Path:
    """The folder a new dataset ``dataset_id`` goes to: a valid id, not taken (creates nothing)."""
    folder = dataset_path(dataset_id)
    if folder.exists():
        raise ValueError(
            f"dataset_id {dataset_id!r}: a dataset with this id already exists in {folder.parent}"
        )
    return folder


def _open(source: str) -> tuple[Any, str]:
    """The dataset at ``source`` (its folder, its ``data`` folder or an id), once its metadata
    has passed :func:`dataset_gate.check_metadata`: Minari never sees a folder we have not read."""
    minari = _minari()
    path = Path(source)
    where = str(path)
    if (path / "data" / METADATA).is_file():
        folder = path / "data"
    elif (path / METADATA).is_file():
        folder = path
    else:
        where = source
        try:
            found: Path | None = dataset_path(source) / "data"
        except DatasetRefused:
            found = None
        if found is None or not (found / METADATA).is_file():
            raise ValueError(
                f"{source}: neither a session log (.jsonl) nor a Minari dataset (an id under "
                "MINARI_DATASETS_PATH, or its folder)"
            )
        folder = found
    check_metadata(folder)
    try:
        return minari.MinariDataset(folder), where
    except Exception as e:  # minari raises many kinds on a broken folder
        raise SessionLogError(f"{source}: cannot read the Minari dataset ({e})") from None


def read_dataset(source: str) -> Session:
    """A Minari dataset written by :func:`export_session` as a Session (exact float64 data)."""
    dataset, where = _open(source)
    try:
        header = json.loads(dataset.storage.metadata[HEADER_KEY])
    except (KeyError, TypeError, ValueError, RecursionError):
        raise SessionLogError(
            f"{where}: not a strol-gym session dataset (no valid header)"
        ) from None
    if not isinstance(header, dict):
        raise SessionLogError(f"{where}: not a strol-gym session dataset (no valid header)")
    header, dims = check_header(f"{where}:header", header)
    episodes = []
    for k, ep in enumerate(dataset.iterate_episodes()):
        at = f"{where}:episode {k}"
        info = ep.infos
        try:
            arrays = {key: np.asarray(info[key], dtype=np.float64) for key in ("x", "u_h", "u_r")}
            arrays["theta_hat"] = np.asarray(info["theta_hat"], dtype=np.float64)
            arrays["theta_star"] = np.asarray(info["theta_star"], dtype=np.float64)
            is_corr = np.asarray(info["is_correction"], dtype=bool)
            ctime = np.asarray(info["correction_time"], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise SessionLogError(
                f"{at}: infos lack x, u_h, u_r, theta_hat or theta_star"
            ) from None
        n = int(is_corr.sum())
        want = {"x": dims["s"], "u_h": dims["a"], "u_r": dims["a"], "theta_hat": dims["d"]}
        want["theta_star"] = dims["d"]
        for key, width in want.items():
            if arrays[key].shape != (n + 1, width):
                raise SessionLogError(f"{at}: infos {key!r} has shape {arrays[key].shape}")
        for key in ("x", "u_h", "u_r"):
            if not np.isfinite(arrays[key]).all():
                raise SessionLogError(f"{at}: infos {key!r} must be finite")
        if not np.isfinite(arrays["theta_hat"][0]).all() or not is_corr[:n].all():
            raise SessionLogError(f"{at}: infos 'theta_hat' or 'is_correction' are malformed")
        star = arrays["theta_star"][0]
        corrections = [
            {
                "x": arrays["x"][i],
                "u_h": arrays["u_h"][i],
                "u_r": arrays["u_r"][i],
                "theta_hat_after": arrays["theta_hat"][i + 1],
                "correction_time": None if np.isnan(ctime[i]) else float(ctime[i]),
            }
            for i in range(n)
        ]
        episodes.append(
            Episode(
                None, arrays["theta_hat"][0], None if np.isnan(star).any() else star, corrections
            )
        )
    if not episodes:
        raise SessionLogError(f"{where}: no episode")
    return Session(Path(where), header, episodes)


def read_any(source: str | Path) -> Session:
    """A session log (a file) or a Minari dataset (an id or a folder)."""
    path = Path(source)
    if path.is_file():
        return read_session(path)
    return read_dataset(str(source))


def export_runs(
    dataset_id: str,
    env: str,
    learner: str,
    condition: str = "training",
    runs: int = 10,
    seed: int = 0,
    corrections: int | None = None,
    task: str | None = None,
    learner_kwargs: dict[str, Any] | None = None,
) -> Any:
    """Benchmark runs as Minari dataset ``dataset_id``: ``learner`` on env preset ``env`` under
    ``condition``, run seeds ``seed … seed + runs − 1`` as ``strol-bench run`` plays them (same
    env kwargs, robot policy and step count), each episode logged and then exported."""
    import tempfile

    import gymnasium as gym

    from strol_gym.benchmarks.engine.conditions import env_preset, make_condition
    from strol_gym.benchmarks.engine.config import Experiment
    from strol_gym.benchmarks.engine.episodes import run_block
    from strol_gym.benchmarks.engine.robots import robot_policy
    from strol_gym.wrappers import OnlineLearningWrapper
    from strol_gym.wrappers.online_learning import learning_env
    from strol_gym.wrappers.session_log import SessionLogger

    new_dataset_path(dataset_id)  # before any work
    _minari()
    exp = Experiment(
        env,
        make_condition(env, condition),
        runs=runs,
        seed=seed,
        n_corrections=corrections,
        task=task,
    )
    genv = gym.make(exp.env_id, **exp.env_kwargs())
    policy = robot_policy(env_preset(env).robot, learning_env(genv).task)
    extra = {
        "benchmark": {
            "env": env,
            "condition": exp.condition.to_dict(),
            "seeds": [seed, seed + runs - 1],
        }
    }
    with tempfile.TemporaryDirectory() as folder:
        logged = SessionLogger(
            OnlineLearningWrapper(genv, learner, learner_kwargs or None, regret=False),
            Path(folder) / "runs.jsonl",
            extra,
        )
        try:
            for run_seed in exp.seeds:
                run_block([(learner, run_seed, logged)], exp.corrections, env, condition, policy)
        finally:
            logged.close()
        return export_session(Path(folder) / "runs.jsonl", dataset_id)


__all__ = ["export_runs", "export_session", "read_any", "read_dataset"]


# ---------------------------------------------------------------------- CLI (strol-bench export)
def add_parser(sub: Any) -> None:
    from strol_gym.benchmarks.args import add_allow_large, plugin_option, positive_int

    p = sub.add_parser(
        "export",
        help="write a session log, or benchmark runs, as a Minari dataset (the [data] extra)",
        description="Write a session log (--log: strol-bench interact, or any SessionLogger) or "
        "benchmark runs (--env, --learner, --condition, --runs, --seed: episodes played as "
        "strol-bench run plays them) as a Minari dataset: one step per correction, float32 "
        "observations (state, correction, θ̂), u_R as the action, exact float64 x, u_H, u_R, θ̂ "
        "and θ* in the infos. Datasets go under MINARI_DATASETS_PATH (default "
        "~/.minari/datasets); strol-bench replay reads them back.",
    )
    p.add_argument("dataset_id", help="Minari dataset id, e.g. strol/study-task1-strol-v0")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--log", help="a session log (.jsonl)")
    what.add_argument("--env", help="benchmark runs on this env preset (strol-bench list)")
    p.add_argument("--learner", default="strol", help="with --env: the learner (default strol)")
    p.add_argument("--condition", default="training", help="with --env: a condition (training)")
    p.add_argument("--runs", type=positive_int("--runs", 10_000), default=10, help="with --env")
    p.add_argument("--seed", type=positive_int("--seed", low=0), default=0, help="first run seed")
    p.add_argument("--corrections", type=positive_int("--corrections"), default=None)
    add_allow_large(p)
    p.add_argument("--task", default=None, help="with --env: a Task name (default: the env's)")
    p.add_argument("--learner-kwargs", default=None, help="with --env: JSON, e.g. '{\"lam\": 0.5}'")
    plugin_option(p)


def command(args: Any, parser: Any) -> int:
    from strol_gym.benchmarks.args import RUN_CAPS, check_size_caps

    check_size_caps(args, RUN_CAPS)
    if args.log is not None:
        dataset = export_session(args.log, args.dataset_id)
    else:
        kwargs = {}
        if args.learner_kwargs:
            try:
                kwargs = json.loads(args.learner_kwargs)
            except (ValueError, RecursionError) as e:
                parser.error(f"--learner-kwargs must be a JSON object ({e})")
            if not isinstance(kwargs, dict):
                parser.error("--learner-kwargs must be a JSON object: the learner's kwargs")
        from strol_gym.benchmarks.args import check_learner_names

        check_learner_names([args.learner])
        dataset = export_runs(
            args.dataset_id,
            args.env,
            args.learner,
            args.condition,
            args.runs,
            args.seed,
            args.corrections,
            args.task,
            kwargs,
        )
    print(
        f"wrote Minari dataset {args.dataset_id}: {dataset.total_episodes} episode(s), "
        f"{dataset.total_steps} correction(s), in {Path(dataset.storage.data_path).parent}"
    )
    return 0
