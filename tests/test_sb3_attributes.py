"""SB3VecEnv against SB3's own DummyVecEnv over the same wrapped sub-envs (a difference test).

Both sides get the same wrapped envs (gymnasium's TimeLimit, the OnlineLearningWrapper and a
wrapper of the test's own with an attribute and a method); whatever DummyVecEnv answers for
``get_attr``/``set_attr``/``env_method``/``env_is_wrapped`` and for stepping, ``SB3VecEnv`` over
a ``SyncVectorEnv`` of them must answer too, in both of gymnasium's autoreset modes.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv, VectorWrapper
from gymnasium.wrappers import RecordEpisodeStatistics, TimeLimit
from stable_baselines3.common.vec_env import DummyVecEnv, VecCheckNan
from strol_gym.wrappers import OnlineLearningWrapper, VectorOnlineLearningWrapper
from strol_gym.wrappers.sb3 import SB3VecEnv

import strol_gym  # noqa: F401

N = 3


class Tagged(gym.Wrapper):
    """A sub-env wrapper with state of its own, to be seen through both vector envs."""

    def __init__(self, env: gym.Env, tag: str) -> None:
        super().__init__(env)
        self.tag = tag

    def tagged(self, suffix: str) -> str:
        return f"{self.tag}-{suffix}"


class Shared(VectorWrapper):
    """A vector wrapper holding one shared value and one row per sub-env."""

    def __init__(self, env) -> None:
        super().__init__(env)
        self.label = "shared"
        self.rows = np.arange(env.num_envs) * 10.0

    def bump(self, by: float) -> np.ndarray:
        self.rows = self.rows + by
        return self.rows


def _makers():
    # Different episode lengths, so episodes end at different steps in the sub-envs.
    def make(i: int):
        env = gym.make("StROL-Robot-v0", max_episode_steps=3 + i)
        return lambda: Tagged(OnlineLearningWrapper(env, "gradient"), f"env{i}")

    return [make(i) for i in range(N)]


def _pair(mode: AutoresetMode = AutoresetMode.NEXT_STEP):
    ours = SB3VecEnv(SyncVectorEnv(_makers(), autoreset_mode=mode))
    theirs = DummyVecEnv(_makers())
    return ours, theirs


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray | float):
        return bool(np.allclose(a, b, atol=1e-6))
    return a == b


@pytest.mark.parametrize("indices", [None, 1, [0, 2]])
def test_attributes_of_wrapped_sub_envs_match_dummy_vec_env(indices):
    ours, theirs = _pair()
    for name in ("tag", "replace_reward", "render_mode", "spec"):  # own wrapper, ours, gymnasium
        assert ours.get_attr(name, indices) == theirs.get_attr(name, indices), name
    task_ours, task_theirs = ours.get_attr("task", indices), theirs.get_attr("task", indices)
    assert [type(t) for t in task_ours] == [type(t) for t in task_theirs]
    for env in (ours, theirs):
        env.set_attr("tag", "renamed", indices)
    assert ours.get_attr("tag") == theirs.get_attr("tag")
    chosen = list(ours._get_indices(indices))
    assert ours.get_attr("tag") == ["renamed" if i in chosen else f"env{i}" for i in range(N)]
    assert ours.env_method("tagged", "x", indices=indices) == theirs.env_method(
        "tagged", "x", indices=indices
    )
    assert ours.env_method("get_wrapper_attr", "tag", indices=indices) == theirs.env_method(
        "get_wrapper_attr", "tag", indices=indices
    )
    for cls in (Tagged, OnlineLearningWrapper, TimeLimit, RecordEpisodeStatistics):
        assert ours.env_is_wrapped(cls, indices) == theirs.env_is_wrapped(cls, indices), cls
    with pytest.raises(AttributeError, match="no_such_thing"):
        ours.get_attr("no_such_thing")
    ours.close()
    theirs.close()


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_steps_and_terminal_observations_match_dummy_vec_env(mode):
    ours, theirs = _pair(mode)
    for env in (ours, theirs):
        env.seed(5)
    assert _same(ours.reset(), theirs.reset())
    assert all(_same(a, b) for a, b in zip(ours.reset_infos, theirs.reset_infos, strict=True))
    rng = np.random.default_rng(0)
    ended = 0
    for t in range(13):  # every sub-env's episode ends at least twice, at different steps
        a = rng.uniform(-1, 1, size=(N, 3)).astype(np.float32)
        obs_o, r_o, d_o, i_o = ours.step(a)
        obs_t, r_t, d_t, i_t = theirs.step(a)
        assert np.array_equal(d_o, d_t) and np.allclose(r_o, r_t, atol=1e-6), t
        assert _same(obs_o, obs_t), t
        for io, it in zip(i_o, i_t, strict=True):
            assert ("terminal_observation" in io) == ("terminal_observation" in it), t
            if "terminal_observation" in it:
                assert _same(io["terminal_observation"], it["terminal_observation"]), t
                assert io["TimeLimit.truncated"] == it["TimeLimit.truncated"]
                assert np.allclose(io["theta_hat"], it["theta_hat"])  # the ending step's info
        assert all(_same(a, b) for a, b in zip(ours.reset_infos, theirs.reset_infos, strict=True))
        ended += int(d_t.sum())
    assert ended >= 2 * N
    ours.close()
    theirs.close()


def test_vec_check_nan_sees_the_same_on_both():
    seen = []
    for env in _pair():
        checked = VecCheckNan(env, raise_exception=True)
        checked.seed(3)
        checked.reset()
        seen.append(checked.step(np.zeros((N, 3), dtype=np.float32))[0])  # finite: passes
        with pytest.raises(ValueError, match="nan in actions"):
            checked.step(np.full((N, 3), np.nan, dtype=np.float32))
        checked.close()
    assert _same(*seen)


def test_vector_wrapper_values_are_shared_or_per_row():
    ours = SB3VecEnv(Shared(SyncVectorEnv(_makers())))
    assert ours.get_attr("label", [0, 2]) == ["shared", "shared"]
    assert ours.get_attr("rows") == [0.0, 10.0, 20.0]  # leading axis num_envs: row i
    assert ours.get_attr("tag", 1) == ["env1"]  # a sub-env's wrapper still seen below
    assert ours.env_is_wrapped(Shared) == [True] * N
    assert ours.env_is_wrapped(Tagged, [0]) == [True]
    with pytest.raises(ValueError, match="'label'"):
        ours.set_attr("label", "mine", indices=[0])
    ours.set_attr("label", "ours")  # all of them: fine
    assert ours.get_attr("label") == ["ours"] * N
    ours.set_attr("rows", -1.0, indices=[1])  # a row each: a subset is fine
    assert ours.get_attr("rows") == [0.0, -1.0, 20.0]
    with pytest.raises(ValueError, match="'bump'"):
        ours.env_method("bump", 1.0, indices=[2])
    assert ours.env_method("bump", 1.0) == [1.0, 0.0, 21.0]
    assert ours.env_method("get_wrapper_attr", "label", indices=[1]) == ["ours"]
    ours.env_method("set_wrapper_attr", "rows", 5.0, indices=[0])
    assert ours.get_attr("rows") == [5.0, 0.0, 21.0]
    with pytest.raises(ValueError, match="'label'"):
        ours.env_method("set_wrapper_attr", "label", "x", indices=[0, 1])
    ours.close()


def test_online_learner_on_the_native_vector_env_shows_its_rows():
    base = gym.make_vec("StROL-Robot-v0", N, vectorization_mode="vector_entry_point")
    ours = SB3VecEnv(VectorOnlineLearningWrapper(base, "gradient"))
    ours.seed(0)
    ours.reset()
    rows = ours.get_attr("theta")
    assert len(rows) == N and all(r.shape == (2,) for r in rows)
    assert np.array_equal(np.stack(rows), ours.env.theta)
    learner = ours.get_attr("learner", [0, 1])
    assert learner[0] is learner[1]  # one learner object on a batch: shared
    assert ours.env_is_wrapped(VectorOnlineLearningWrapper) == [True] * N
    assert ours.env_is_wrapped(Tagged) == [False] * N
    ours.close()


def test_modes_other_than_next_and_same_step_are_refused():
    env = SyncVectorEnv(_makers(), autoreset_mode=AutoresetMode.DISABLED)
    with pytest.raises(ValueError, match="autoreset mode"):
        SB3VecEnv(env)
    with pytest.raises(TypeError, match="VectorEnv"):
        SB3VecEnv(_makers()[0]())  # type: ignore[arg-type]


def test_ppo_smoke_on_same_step_wrapped_sub_envs():
    import torch
    from stable_baselines3 import PPO

    env = VecCheckNan(SB3VecEnv(SyncVectorEnv(_makers(), autoreset_mode=AutoresetMode.SAME_STEP)))
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # a tiny policy: more threads only contend with the other workers
    model = PPO("MultiInputPolicy", env, n_steps=8, batch_size=24, n_epochs=1, seed=0)
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(total_timesteps=2 * 8 * N)
    assert model.num_timesteps == 2 * 8 * N
    after = list(model.policy.parameters())
    torch.set_num_threads(threads)
    assert any(not torch.equal(a, b) for a, b in zip(before, after, strict=True))
    env.close()
