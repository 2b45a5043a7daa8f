"""Fingerprint of the shipped results: small runs of every benchmark command and env rollouts.

A refactor that claims "same behaviour" runs this before and after and diffs the two outputs:

    .venv/bin/python lab/checks/byte_identity.py --out /tmp/before.txt
    (change the code)
    .venv/bin/python lab/checks/byte_identity.py --out /tmp/after.txt
    diff /tmp/before.txt /tmp/after.txt

Each line is `name sha256` of a results CSV (small configs: a few runs, two study users per
Task) or of one env episode (observations, rewards, flags) from a fixed seed with the env's
default arguments and seeded random actions.
"""

from __future__ import annotations

import argparse
import hashlib
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BENCH = [sys.executable, "-m", "strol_gym.benchmarks"]
RUNS = {
    "paper": ["paper", "--env", "all", "--runs", "3"],
    "changing-robot": ["changing", "--env", "robot", "--runs", "3"],
    "changing-highway": ["changing", "--env", "highway", "--runs", "3"],
    "lambda": ["lambda", "--runs", "3", "--lambdas", "0,1"],
    "study-v0": ["study", "--env-version", "v0", "--users", "2"],
    "study-v1": ["study", "--env-version", "v1", "--users", "1"],
    "study-v2": ["study", "--env-version", "v2", "--users", "1"],
}
ENVS = ["StROL-Robot-v0", "StROL-Highway-v0", "StROL-Study-v0", "StROL-Study-v1", "StROL-Study-v2"]


def run_hashes(name: str, args: list[str], tmp: Path) -> list[str]:
    """Runs one benchmark command into a fresh folder and hashes every CSV it wrote."""
    out = tmp / name
    cmd = [*BENCH, *args, "--out", str(out), "--jobs", "1", "--quiet", "--no-plots"]
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return [
        f"{name}/{p.relative_to(out)} {hashlib.sha256(p.read_bytes()).hexdigest()}"
        for p in sorted(out.rglob("*.csv"))
    ]


def env_hash(env_id: str, steps: int = 40) -> str:
    """One episode's bytes (observation, reward, flags) from seed 7 with seeded random actions."""
    import gymnasium as gym
    import numpy as np

    import strol_gym  # noqa: F401  (registers the envs)

    env = gym.make(env_id)
    h = hashlib.sha256()
    obs, _ = env.reset(seed=7)
    env.action_space.seed(7)
    space = env.observation_space
    h.update(np.asarray(gym.spaces.flatten(space, obs), dtype=np.float64).tobytes())
    for _ in range(steps):
        obs, reward, term, trunc, _ = env.step(env.action_space.sample())
        h.update(np.asarray(gym.spaces.flatten(space, obs), dtype=np.float64).tobytes())
        h.update(np.float64(reward).tobytes() + bytes([term, trunc]))
        if term or trunc:
            break
    env.close()
    return f"env/{env_id} {h.hexdigest()}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="where the fingerprint goes")
    parser.add_argument("--only", default="", help="comma-separated subset of runs/envs")
    args = parser.parse_args()
    only = set(filter(None, args.only.split(",")))
    lines: list[str] = []
    for env_id in ENVS:
        if not only or env_id in only or "env" in only:
            lines.append(env_hash(env_id))
            print(lines[-1], flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name, cmd in RUNS.items():
            if only and name not in only:
                continue
            lines += run_hashes(name, cmd, Path(tmp))
            print(name, "done", flush=True)
    args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
