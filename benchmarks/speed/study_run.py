"""Wall time of ``strol-bench study`` (all Tasks, the five learners) with the strol-gym this
interpreter imports, for before/after comparisons of the simulated study's speed.

    .venv/bin/python benchmarks/speed/study_run.py [--users 20] [--jobs 2] [--out DIR]

Runs the study as a child process (``python -m strol_gym.benchmarks study ... --no-plots``)
into ``--out`` (a fresh folder under the system's temporary one by default) and prints its wall
time, the CPU time of its processes (user + system, the workers included) and the load average
before and after. On a shared machine run the two versions side by side, at the same time:
their wall times then meet the same load, and the CPU times do not depend on it much.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time


def run_study(users: int, jobs: int, out: str) -> tuple[float, float]:
    """(wall s, CPU s of the study's processes)."""
    cmd = [sys.executable, "-m", "strol_gym.benchmarks", "study", "--users", str(users)]
    cmd += ["--jobs", str(jobs), "--no-plots", "--quiet", "--force", "--out", out]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--users", type=int, default=20, help="simulated users per Task (20)")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (2)")
    p.add_argument("--out", default=None, help="results folder (default: a temporary one)")
    args = p.parse_args()
    import strol_gym

    out = args.out or tempfile.mkdtemp(prefix="study-speed-")
    print(f"strol-gym from {os.path.dirname(strol_gym.__file__)}; results in {out}")
    print(f"load average before: {os.getloadavg()[0]:.2f}", flush=True)
    wall, cpu = run_study(args.users, args.jobs, out)
    print(
        f"strol-bench study --users {args.users} --jobs {args.jobs}: wall {wall:.1f} s, "
        f"CPU {cpu:.1f} s; load average after: {os.getloadavg()[0]:.2f}"
    )


if __name__ == "__main__":
    main()
