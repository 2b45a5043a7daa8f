"""Start-up time of ``strol-bench --help`` and ``strol-bench list`` (target: ``--help`` within
0.5 s on an idle core), and which heavy stacks each start-up imports (none should).

    .venv/bin/python -m lab.speed.cli_start [--repeats 5]

Each figure is the wall time of a fresh ``strol-bench`` process (the venv's console script, as
a user runs it), best and median of ``--repeats``; the CPU time (user + system) of the same
process is printed beside it, since on a shared machine the wall time also holds the waits for
a core. The load average is printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

HEAVY = ("torch", "scipy", "mujoco", "matplotlib", "highway_env", "safetensors", "numba")
TARGET_S = 0.5
PROBE = """
import contextlib, io, sys
from strol_gym.benchmarks.cli import main
with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
    main(sys.argv[1:])
print(",".join(sorted({m.split(".")[0] for m in sys.modules} & set(sys.argv[0].split(",")))))
"""


def _bench() -> list[str]:
    script = Path(sys.executable).with_name("strol-bench")
    return [str(script)] if script.exists() else [sys.executable, "-m", "strol_gym.benchmarks"]


def timed(argv: list[str]) -> tuple[float, float]:
    """Wall and CPU seconds of one fresh ``strol-bench argv`` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([*_bench(), *argv], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def heavy_imports(argv: list[str]) -> str:
    """The heavy stacks a start-up with ``argv`` imports (empty: none)."""
    out = subprocess.run(
        [sys.executable, "-c", PROBE.replace("sys.argv[0]", repr(",".join(HEAVY))), *argv],
        check=True,
        capture_output=True,
        text=True,
    )
    return out.stdout.strip() or "none"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} (1 min)")
    for argv in (["--help"], ["list"]):
        runs = [timed(argv) for _ in range(args.repeats)]
        walls = sorted(w for w, _ in runs)
        cpus = sorted(c for _, c in runs)
        target = f" (target <= {TARGET_S} s idle)" if argv == ["--help"] else ""
        print(
            f"strol-bench {' '.join(argv)}: wall best {walls[0]:.3f} s, median "
            f"{statistics.median(walls):.3f} s; CPU best {cpus[0]:.3f} s{target}; "
            f"heavy stacks imported: {heavy_imports(argv)}"
        )
    print(f"load average {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
