"""A short StROL-Robot-v0 rollout, rendered to a GIF and a PNG whose paths it prints.

    .venv/bin/python benchmarks/examples/demo_robot.py [--seed 0] [--learner strol] [--out DIR]

A simulated human (eq. M6, 25 % noise) with hidden θ* corrects the Panda during the first 5
of 12 steps; the learner updates θ̂ after each correction; the robot moves by the first step
of ``RobotTask.plan`` for its current θ̂ (``task.robot_policy``). The GIF shows the whole
episode, the PNG its last frame; the console shows θ*, θ̂ and the regret of θ̂.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
from numpy.typing import ArrayLike

import strol_gym
from strol_gym.wrappers.online_learning import learning_env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--learner", default="strol", choices=strol_gym.list_learners())
    parser.add_argument("--steps", type=int, default=12)
    parser.add_argument("--out", type=Path, default=Path("results/demo"))
    args = parser.parse_args()

    env = gym.make(
        "StROL-Robot-v0",
        person={"sigma": 0.25},
        render_mode="rgb_array",
        width=480,
        height=360,
        max_episode_steps=args.steps,
    )
    robot = learning_env(env)
    task = robot.task
    learner = strol_gym.make_learner(args.learner, task=task)
    obs, info = env.reset(seed=args.seed)
    theta_hat = learner.reset()
    x0, theta_star = obs["state"].astype(np.float64), info["theta_star"]

    def render() -> np.ndarray:
        frame = env.render()
        assert isinstance(frame, np.ndarray)  # render_mode="rgb_array": one RGB frame
        return frame

    frames: list[ArrayLike] = [render()]
    done = False
    while not done:
        x = obs["state"].astype(np.float64)
        u_r = task.robot_policy(x, theta_hat)[0]
        obs, _, term, trunc, info = env.step((u_r / task.robot_action_bound).astype(np.float32))
        if info["is_correction"]:
            theta_hat = learner.update(x, info["correction"], info["robot_action"])
            robot.set_theta_hat(theta_hat)
        frames.append(render())
        done = term or trunc
    env.close()

    args.out.mkdir(parents=True, exist_ok=True)
    gif, png = args.out / "robot_rollout.gif", args.out / "robot_final.png"
    imageio.mimsave(gif, frames, duration=0.25, loop=0)
    imageio.imwrite(png, frames[-1])
    regret = float(task.regret(theta_hat, theta_star, x0)[0])
    print(f"θ* = {np.round(theta_star, 3)}, θ̂ ({args.learner}) = {np.round(theta_hat, 3)}")
    print(f"regret of θ̂ from the start state: {regret:.3f}")
    print(f"wrote {gif.resolve()}")
    print(f"wrote {png.resolve()}")


if __name__ == "__main__":
    main()
