"""Participants per core that ``strol-bench serve`` holds at real time, and what their pages see.

For N = 1, 2, ... simulated participants at once (websocket clients on 127.0.0.1, no browser:
the page's own work is the browser's), each runs an arm session (the heavier kind: physics,
the learner and offscreen frames) for ``--seconds`` of simulated time, pushing the cup for
0.5 s every 2 s. Per N it prints the sessions' real-time factors (simulated over wall-clock
seconds, as ``interact`` reports it), the frames a second a page received, the input latency
(a key message sent -> the first frame rendered after the env applied it, at the page) and the
CPU share of each session's process. Participants per core: the largest N whose every session
kept a real-time factor >= 0.95, over the machine's cores. The load average is printed beside:
on a shared machine the figures move with it.

    python -m strol_gym.benchmarks.speed.serve_load [--max N] [--seconds S] [--fps F]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

TARGET_RTF = 0.95
TOKEN = "load-benchmark"


async def participant(url: str, push_every: float = 2.0) -> dict[str, Any]:
    """One simulated page: start the session, push now and then, time frames and inputs."""
    import websockets

    sent: dict[int, float] = {}
    latency: list[float] = []
    frames: list[float] = []
    n = 0
    async with websockets.connect(url.replace("http", "ws") + f"/ws?token={TOKEN}") as ws:

        async def pushes() -> None:
            nonlocal n
            while True:
                await asyncio.sleep(push_every)
                for held in (["d"], []):
                    n += 1
                    sent[n] = time.perf_counter()
                    await ws.send(json.dumps({"t": "input", "n": n, "keys": held, "pad": None}))
                    await asyncio.sleep(0.5)

        pusher: asyncio.Task | None = None
        try:
            while True:
                m = await ws.recv()
                if isinstance(m, bytes):
                    now = time.perf_counter()
                    frames.append(now)
                    ack = int.from_bytes(m[:4], "big")
                    if ack in sent:
                        latency.append(now - sent.pop(ack))
                    if pusher is None:
                        pusher = asyncio.create_task(pushes())
                    continue
                msg = json.loads(m)
                if msg["t"] == "next":
                    await ws.send(json.dumps({"t": "start"}))
                elif msg["t"] == "ended":
                    end = msg
                    break
        finally:
            if pusher is not None:
                pusher.cancel()
    wall = frames[-1] - frames[0] if len(frames) > 1 else float("nan")
    return {
        "rtf": end["real_time_factor"],
        "fps": (len(frames) - 1) / wall,
        "latency": latency,
        "cpu": end.get("cpu_share"),
        "reason": end["reason"],
    }


def measure(n: int, seconds: float, fps: float) -> list[dict[str, Any]]:
    from strol_gym.benchmarks.serve.app import Server, serve_in_thread
    from strol_gym.benchmarks.serve.plan import StudyPlan

    with tempfile.TemporaryDirectory() as out:
        plan = StudyPlan(practice=seconds, highway=False)
        server = Server(plan, Path(out), TOKEN, fps=fps, max_visits=n)
        with serve_in_thread(server) as url:

            async def all_of_them() -> list[dict[str, Any]]:
                return await asyncio.gather(*(participant(url) for _ in range(n)))

            return asyncio.run(all_of_them())


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m strol_gym.benchmarks.speed.serve_load")
    p.add_argument("--max", type=int, default=4, help="most participants at once (4)")
    p.add_argument("--seconds", type=float, default=30.0, help="simulated s per session (30)")
    p.add_argument("--fps", type=float, default=8.0, help="the arm's frames a second (8)")
    a = p.parse_args(argv)
    if not 1 <= a.max <= 16 or not 5 <= a.seconds <= 600 or not 1 <= a.fps <= 30:
        p.error("--max in [1, 16], --seconds in [5, 600], --fps in [1, 30]")
    cores = os.cpu_count() or 1
    print(f"{cores} cores; load average before: {os.getloadavg()[0]:.1f}")
    print(" N  RTF min  RTF mean  frames/s  latency ms (median, p95)  CPU/participant")
    best = 0
    for n in range(1, a.max + 1):
        runs = measure(n, a.seconds, a.fps)
        rtf = [r["rtf"] for r in runs]
        lat = sorted(x * 1000 for r in runs for x in r["latency"])
        p95 = lat[int(0.95 * (len(lat) - 1))] if lat else float("nan")
        med = statistics.median(lat) if lat else float("nan")
        cpu = [r["cpu"] for r in runs if r["cpu"] is not None]
        print(
            f"{n:2d}  {min(rtf):7.3f}  {statistics.mean(rtf):8.3f}  "
            f"{statistics.mean(r['fps'] for r in runs):8.2f}  {med:10.0f} {p95:10.0f}"
            f"            {statistics.mean(cpu):.2f}   (load {os.getloadavg()[0]:.1f})"
        )
        print(f"    each session's RTF: {', '.join(f'{x:.3f}' for x in rtf)}")
        if min(rtf) >= TARGET_RTF:
            best = n
    print(
        f"participants per core at a real-time factor >= {TARGET_RTF}: {best / cores:.1f} "
        f"({best} on {cores} cores); load average after: {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main()
