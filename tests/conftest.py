"""Shared test setup: headless rendering backends, set before any test imports a renderer."""

from __future__ import annotations

import os

# MuJoCo picks its OpenGL backend at import; EGL renders without a display.
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
# Reports' bootstrap intervals: 200 resamples in tests (the benchmark's default is 2,000);
# set here so the strol-bench subprocesses that tests start inherit it.
os.environ.setdefault("STROL_BOOTSTRAP_RESAMPLES", "200")

import pytest


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_a_temporary_folder(tmp_path_factory: pytest.TempPathFactory) -> None:
    """stable-baselines3 makes a log folder for every ``learn`` given none (``/tmp/SB3-<date>``
    by default); the tests' go under pytest's own temporary folder, which pytest prunes."""
    os.environ.setdefault("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3-logs")))


@pytest.fixture(autouse=True)
def _size_caps_as_found():
    """A test that lifts the size caps (``--allow-large``, ``check_size_caps``) leaves them as
    it found them: the next test in the same worker is capped again."""
    from strol_gym import limits

    before = limits.lifted_now()
    yield
    limits.lift(before)


@pytest.fixture(scope="session")
def authors_tree(tmp_path_factory: pytest.TempPathFactory):
    """A factory of fake study trees in the authors' layout, ``data/user_K/task_J/ALG/data.pkl``
    (``test_study_import``'s session writer; nothing of the authors'): ``people`` people (user_1
    ...) x ``tasks`` x One, MOF and StROL (b1, b2, ours), each session with one correction per
    entry of ``sizes`` (``ours_sizes`` for StROL's; None: the same), those of ≥ 2 poses moving
    the cup by one of two moves drawn uniform in ±``scale`` per axis from ``seed``, the angles
    weighted by ``turn`` (Task 1's are 0). ``moves``, if given, receives each session's moves
    by (user, task, alg). Returns the ``data`` folder."""
    from pathlib import Path

    import numpy as np

    def make(
        *,
        people: int,
        seed: int,
        tasks: tuple[int, ...] = (1, 2, 3),
        scale: float = 0.1,
        turn: tuple[float, float, float] = (0.5, 0.5, 0.5),
        sizes: tuple[int, ...] = (5, 0, 1, 3),
        ours_sizes: tuple[int, ...] | None = None,
        moves: dict | None = None,
    ) -> Path:
        from test_study_import import _session, _write

        root = tmp_path_factory.mktemp("authors") / "data"
        rng = np.random.default_rng(seed)
        for p in range(people):
            for task in tasks:
                for alg in ("b1", "b2", "ours"):
                    mv = [rng.uniform(-scale, scale, 6) * [1, 1, 1, *turn] for _ in range(2)]
                    if task == 1:
                        mv = [np.concatenate([v[:3], np.zeros(3)]) for v in mv]
                    if moves is not None:
                        moves[(f"user_{p + 1}", task, alg)] = mv
                    n = sizes if alg != "ours" or ours_sizes is None else ours_sizes
                    _write(root, f"user_{p + 1}", task, alg, _session(task, rng, mv, list(n)))
        return root

    return make
