"""Gymnasium envs: StROL-Robot-v0 (strol_gym.envs.robot) and StROL-Highway-v0 (.highway).

Modules are imported by ``gymnasium.make`` through the entry points in
strol_gym.registration, so importing this package loads neither MuJoCo nor highway-env.
"""
