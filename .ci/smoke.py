"""The smoke test of an installed wheel (.ci/oldest's first step, run outside the source tree):
every registered env makes, resets and steps, and a learner updates θ̂ from a human's correction."""

import warnings

import gymnasium as gym
import numpy as np

import strol_gym
from strol_gym.wrappers import OnlineLearningWrapper

warnings.simplefilter("ignore", DeprecationWarning)  # Study-v0 and -v1 are deprecated, still made
ids = sorted(i for i in gym.registry if i.startswith("StROL-"))
assert ids, "no StROL env registered"
for env_id in ids:
    env = gym.make(env_id)
    env.reset(seed=0)
    env.action_space.seed(0)
    env.step(env.action_space.sample())
    env.close()
print("made, reset and stepped:", " ".join(ids))

env = gym.make("StROL-Robot-v0", sigma=0.25)
task = env.unwrapped.task
env = OnlineLearningWrapper(env, strol_gym.make_learner("strol", task=task))
obs, _ = env.reset(seed=0)
theta0 = np.array(obs["theta_hat"])
u_r = task.robot_policy(obs["state"], obs["theta_hat"])[0]
obs, *_ = env.step(u_r / task.robot_action_bound)
moved = float(np.linalg.norm(obs["theta_hat"] - theta0))
assert moved > 0, "one correction left θ̂ where it was"
print(f"strol's update moved θ̂ by {moved:.4f} ({strol_gym.__file__})")
