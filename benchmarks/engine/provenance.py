"""What a benchmark's records depend on besides its config: the code, the shipped data and
the learners' weights, fingerprinted so that a results folder is never resumed with other code."""

from __future__ import annotations

import hashlib
from typing import Any

from strol_gym.benchmarks.engine.config import BenchConfig

from strol_gym.learners.checkpoint import checkpoint_sha256
from strol_gym.learners.registry import make_learner
from strol_gym.provenance import NUMERIC_PACKAGES

__all__ = ["NUMERIC_PACKAGES", "check_learners", "code_fingerprint", "learner_fingerprint"]

# What a record depends on besides the run's config: every module of the strol_gym package
# except the benchmark's report-only modules (tables, plots, statistics, the CLI), plus the
# shipped data, by data package and the suffixes setup.cfg installs. (The study's metrics the
# authors' way, a recorded value, live in strol_gym.envs.study.metrics, so they count.)
BENCHMARK_CODE = (
    "engine",
    "engine.config",
    "engine.conditions",
    "engine.episodes",
    "engine.robots",
    "engine.worker",
)
MAPPED_PACKAGES = ("strol_gym.wrappers", "strol_gym.benchmarks")
DATA_FILES = {
    "strol_gym.assets": (".xml", ".npz"),
    "strol_gym.pretrained": (".safetensors", ".json"),
}


def _code_modules(package: str = "strol_gym") -> list[str]:
    """Names of ``package`` and all its submodules, found through the import system (so an
    editable and a wheel install list the same modules, whatever their files' layout)."""
    import importlib
    import pkgutil

    names = [package]
    pkg = importlib.import_module(package)
    found = {i.name: i.ispkg for i in pkgutil.iter_modules(pkg.__path__, package + ".")}
    if package == "strol_gym":
        # setup.cfg maps these from the repository's top level (package_dir): an editable
        # install imports them but does not list them under strol_gym's folder.
        found.update(dict.fromkeys(MAPPED_PACKAGES, True))
    for name, ispkg in sorted(found.items()):
        if name == "strol_gym.benchmarks":
            names += [f"{name}.{m}" for m in BENCHMARK_CODE]
        elif ispkg:
            names += _code_modules(name)
        else:
            names.append(name)
    return names


def code_fingerprint() -> str:
    """SHA-256 of the code and data that produce records: each strol_gym module's source (tasks,
    envs, humans, learners, wrappers, the benchmark's episode loop, worker, config and
    conditions)
    under its module name, and the shipped assets and weights under their package-relative
    names.

    Part of the config hash, so a results folder is never resumed with other code: a resumed
    run would otherwise mix records from two versions. Report-only modules are left out, so
    re-rendering with newer tables or plots still works. Hashing by module name, not by file
    listing, gives the same fingerprint for an editable and a wheel install of one commit.
    """
    import importlib.resources
    import importlib.util

    h = hashlib.sha256()
    for name in sorted(_code_modules()):
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None or spec.loader is None:
            raise RuntimeError(f"cannot find the source of module {name!r} to fingerprint it")
        source = spec.loader.get_data(spec.origin)  # type: ignore[attr-defined]
        h.update(f"module:{name}".encode() + b"\0" + source + b"\0")
    for package, suffixes in DATA_FILES.items():
        root = importlib.resources.files(package)
        files = sorted((f.name, f) for f in root.iterdir() if f.name.endswith(suffixes))
        for fname, f in files:
            h.update(f"data:{package}/{fname}".encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def learner_fingerprint(learner: Any) -> dict[str, Any]:
    """What identifies a learner's behaviour: class, config and a hash of its checkpoint (the
    weights file and its sidecar together: the sidecar's network and bound matter as much)."""
    fp: dict[str, Any] = {"class": f"{type(learner).__module__}.{type(learner).__qualname__}"}
    config = getattr(learner, "config", None)
    if callable(config):
        fp["config"] = config()
    ckpt = getattr(learner, "checkpoint", None)
    if ckpt:
        fp["checkpoint_sha256"] = checkpoint_sha256(ckpt)[:16]
    return fp


def check_learners(config: BenchConfig) -> dict[str, Any]:
    """Build every learner for every env once (before any work) and return their fingerprints.

    Raises ValueError for an unknown learner or one that cannot be built for an env's task.
    """
    import gymnasium as gym

    import strol_gym  # noqa: F401  (registers the envs)

    out: dict[str, Any] = {}
    for env_key in dict.fromkeys(e.env for e in config.experiments):
        exp = next(e for e in config.experiments if e.env == env_key)
        env = gym.make(exp.env_id, **exp.env_kwargs())
        try:
            task = env.unwrapped.task
            out[env_key] = {}
            for name in config.learners:
                try:
                    learner = make_learner(name, task=task, **config.kwargs_for(name))
                except (OSError, TypeError) as e:
                    raise ValueError(
                        f"learner {name!r} cannot be built for {exp.env_id}: {e}"
                    ) from e
                out[env_key][name] = learner_fingerprint(learner)
        finally:
            env.close()
    return out
