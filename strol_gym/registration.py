"""Gymnasium registration of the strol-gym envs. Idempotent: safe to import twice."""

from __future__ import annotations

import gymnasium as gym

from strol_gym.envs.study.versions import VERSIONS

ENV_SPECS: dict[str, dict] = {
    # gymnasium's TimeLimit ends episodes: 10 steps unless make(..., max_episode_steps=N).
    "StROL-Robot-v0": {
        "entry_point": "strol_gym.envs.robot.env:RobotEnv",
        "vector_entry_point": "strol_gym.envs.robot.vector:VectorRobotEnv",
        "max_episode_steps": 10,
    },
    # The study env truncates itself after 60 s of simulated time (1200 steps of 0.05 s); one
    # id per version (versions.VERSIONS). v0 and v1 are kept for the published results;
    # gymnasium warns on make that the latest supersedes them.
    **{
        v.env_id: {
            "entry_point": f"strol_gym.envs.study.env:{v.env_class}",
            "max_episode_steps": 1200,
        }
        for v in VERSIONS.values()
    },
    "StROL-Highway-v0": {
        "entry_point": "strol_gym.envs.highway.env:HighwayEnv",
        "vector_entry_point": "strol_gym.envs.highway.vector:VectorHighwayEnv",
        "max_episode_steps": 10,
    },
}


def register_envs() -> None:
    """Register every env id once; a second call (or a re-import) changes nothing."""
    for env_id, spec in ENV_SPECS.items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point=spec["entry_point"],
                max_episode_steps=spec["max_episode_steps"],
                vector_entry_point=spec.get("vector_entry_point"),
            )
