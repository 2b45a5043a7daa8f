"""gymnasium's RecordVideo writes an MP4 of every strol-gym env (the [video] extra: moviepy)."""

from __future__ import annotations

import importlib.util

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import RecordVideo

import strol_gym  # noqa: F401  (registers the envs)

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("moviepy") is None,
    reason='moviepy is not installed (pip install ".[video]")',
)

SIZES = {
    "StROL-Robot-v0": {"width": 96, "height": 64},
    "StROL-Highway-v0": {"width": 120, "height": 60},
    "StROL-Study-v0": {"width": 96, "height": 64},
    "StROL-Study-v1": {"width": 96, "height": 64},
}


@pytest.mark.parametrize("env_id", sorted(SIZES))
def test_record_video_writes_an_mp4(tmp_path, env_id):
    env = RecordVideo(
        gym.make(env_id, render_mode="rgb_array", **SIZES[env_id]),
        video_folder=str(tmp_path / "videos"),
        name_prefix="clip",
        episode_trigger=lambda k: k == 0,
        disable_logger=True,
    )
    env.reset(seed=0)
    for _ in range(4):
        env.step(np.zeros(env.action_space.shape, dtype=env.action_space.dtype))
    env.close()
    videos = sorted((tmp_path / "videos").glob("clip-episode-0.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 500

    from moviepy import VideoFileClip

    with VideoFileClip(str(videos[0])) as clip:
        assert clip.size == [SIZES[env_id]["width"], SIZES[env_id]["height"]]
        if env_id == "StROL-Highway-v0":  # a 2 Hz env: one frame per step plays in real time
            assert clip.fps == 1 / env.unwrapped.task.dt == 2
        frames = list(clip.iter_frames())
    assert len(frames) == 5  # the reset's frame and one per step
