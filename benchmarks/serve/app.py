"""The web server of ``strol-bench serve``: the page, the participant's visit, the sessions.

A visit is one websocket: the server gives the visitor an anonymous id and their sessions
(:mod:`plan`), then for each one waits for the page's "start", runs it in a process of its own
(:mod:`worker`) and relays frames and the panel to the page and the page's keys to the env,
until the session ends (time up), the page goes away (the session ends with reason
"connection closed") or the page misbehaves (closed with code 1008). Every path the server
writes is its own (``out/<id>/NN-....jsonl``); the page names none.

Every route but the page's two static files needs the server's token in the link
(``?token=...``), on loopback too: another user of the same machine can reach 127.0.0.1.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import hmac
import json
import multiprocessing
import os
import threading
import time
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import JSONResponse, PlainTextResponse, Response
from starlette.routing import Route, WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from strol_gym.benchmarks.serve import inputs
from strol_gym.benchmarks.serve.plan import Participants, SessionSpec, StudyPlan
from strol_gym.benchmarks.sessions import keys as keymap

PAGE_FILES = {
    "/": ("index.html", "text/html; charset=utf-8"),
    "/page.js": ("page.js", "text/javascript; charset=utf-8"),
    "/page.css": ("page.css", "text/css; charset=utf-8"),
}
SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; img-src 'self' blob:; "
    "connect-src 'self'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}
WS_MAX_SIZE = 4096
"""Bytes in one websocket message at most (uvicorn closes the connection, 1009, beyond)."""
START_WAIT = 900.0
"""s a page may wait before starting its next session; then the visit ends."""
MAX_REFUSED = 20
"""Refused messages a connection may send before it is closed."""
MAX_DROPPED = 300
"""Messages over the rate limit a connection may send before it is closed."""
STOP_WAIT = 15.0
"""s a session's process has to write its ``end`` line after a stop, before it is killed."""
PRELOAD = [
    "strol_gym.benchmarks.serve.worker",
    "strol_gym.envs.study.env",
    "strol_gym.envs.highway.env",
    "strol_gym.learners",
    "strol_gym.learners.correction",
    "strol_gym.benchmarks.engine.robots",
    "highway_env",
]
"""What the fork server imports once, so that a session's process need not: torch alone (the
learners' ĝ) took 6.8 s of a first session's 8 s start (load 9)."""


class Policy(Exception):
    """The page broke the rules (too many refused or too many messages): close with 1008."""


@dataclasses.dataclass
class Visit:
    """One page's connection: its rate limit, the current session's pipe, its "start"s."""

    ws: WebSocket
    limit: inputs.RateLimit = dataclasses.field(default_factory=inputs.RateLimit)
    refused: int = 0
    dropped: int = 0
    conn: Any = None
    starts: asyncio.Queue = dataclasses.field(default_factory=asyncio.Queue)
    gone: asyncio.Event = dataclasses.field(default_factory=asyncio.Event)
    why_gone: str = "connection closed"


class Server:
    """The app and what it holds: the plan, the participants, the worker processes."""

    def __init__(
        self,
        plan: StudyPlan,
        out: Path,
        token: str,
        fps: float = 8.0,
        max_visits: int = 4,
    ) -> None:
        os.environ.setdefault("MUJOCO_GL", "egl")  # before the fork server starts
        os.environ.setdefault("SDL_VIDEODRIVER", "offscreen")
        self.plan, self.out, self.token = plan, Path(out), token
        self.fps, self.max_visits = fps, max_visits
        self.participants = Participants(self.out, plan)
        self.visits = 0
        self.ctx = multiprocessing.get_context("forkserver")
        self.ctx.set_forkserver_preload(PRELOAD)
        # the fork server's imports take seconds: begin them now, not when someone waits
        threading.Thread(target=self._warm, daemon=True).start()
        static = resources.files("strol_gym.benchmarks.serve") / "static"
        self.pages = {
            route: (static.joinpath(name).read_bytes(), kind)
            for route, (name, kind) in PAGE_FILES.items()
        }
        self.app = Starlette(
            routes=[
                Route("/", self.page),
                Route("/page.js", self.page),
                Route("/page.css", self.page),
                Route("/api/intro", self.intro),
                WebSocketRoute("/ws", self.visit),
            ]
        )

    def _warm(self) -> None:
        proc = self.ctx.Process(target=_nothing, daemon=True)
        proc.start()
        proc.join()

    # ------------------------------------------------------------------ HTTP
    def _token_ok(self, query: Any) -> bool:
        given = query.get("token", "")
        return hmac.compare_digest(given.encode(), self.token.encode())

    async def page(self, request: Request) -> Response:
        path = request.url.path
        if path == "/" and not self._token_ok(request.query_params):
            return PlainTextResponse("a valid token is required (?token=...)", 403)
        body, kind = self.pages[path]
        return Response(body, media_type=kind, headers=SECURITY_HEADERS)

    async def intro(self, request: Request) -> Response:
        if not self._token_ok(request.query_params):
            return PlainTextResponse("a valid token is required (?token=...)", 403)
        _, sessions = self.participants.preview()
        body = {
            "study": self.plan.name,
            "consent": self.plan.consent,
            "sessions": [s.label for s in sessions],
            "arm_keys": list(keymap.ARM_KEY_HELP),
            "car_keys": list(keymap.CAR_KEY_HELP),
            "known_keys": sorted(inputs.KNOWN_KEYS),
        }
        return JSONResponse(body, headers=SECURITY_HEADERS)

    # ------------------------------------------------------------------ a visit
    async def visit(self, ws: WebSocket) -> None:
        if not self._token_ok(ws.query_params):
            await ws.close(code=1008)
            return
        await ws.accept()
        if self.visits >= self.max_visits:
            await ws.send_text(json.dumps({"t": "full"}))
            await ws.close(code=1013)
            return
        self.visits += 1
        v = Visit(ws)
        reader = asyncio.create_task(self._read(v))
        try:
            pid, _, sessions = self.participants.join()
            await self._send(v, {"t": "hello", "participant": pid, "sessions": len(sessions)})
            for i, spec in enumerate(sessions):
                await self._send(v, _next(i, spec))
                if not await self._wait_start(v):
                    return
                end = await self._session(v, pid, i, spec)
                await self._send(v, {"t": "ended", **end})
                if v.gone.is_set():
                    return
            await self._send(v, {"t": "done", "participant": pid})
            with contextlib.suppress(Exception):
                await ws.close()
        finally:
            self.visits -= 1
            reader.cancel()
            with contextlib.suppress(BaseException):
                await reader

    async def _send(self, v: Visit, message: dict[str, Any] | bytes) -> None:
        if v.gone.is_set():
            return
        try:
            if isinstance(message, bytes):
                await v.ws.send_bytes(message)
            else:
                await v.ws.send_text(json.dumps(message))
        except Exception:  # the page went away mid-send
            v.gone.set()

    async def _read(self, v: Visit) -> None:
        """Every message of the visit: checked, rate-limited, then a "start" for the visit or
        keys for the running session. A page that breaks the rules is closed (1008)."""
        try:
            while True:
                message = await v.ws.receive()
                if message["type"] == "websocket.disconnect":
                    break
                if not v.limit.allow():
                    v.dropped += 1
                    if v.dropped > MAX_DROPPED:
                        raise Policy("too many messages")
                    continue
                try:
                    checked = inputs.parse(message.get("text"))
                except inputs.Refused as e:
                    v.refused += 1
                    await self._send(v, {"t": "refused", "why": str(e)[:200]})
                    if v.refused > MAX_REFUSED:
                        raise Policy("too many refused messages") from None
                    continue
                if checked["t"] == "start":
                    v.starts.put_nowait(True)
                elif v.conn is not None:
                    with contextlib.suppress(OSError, ValueError):
                        v.conn.send(("input", checked))
        except Policy as e:
            v.why_gone = f"connection closed by the server ({e})"
            with contextlib.suppress(Exception):
                await v.ws.close(code=1008)
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            v.gone.set()
            if v.conn is not None:
                with contextlib.suppress(OSError, ValueError):
                    v.conn.send(("stop", v.why_gone))

    async def _wait_start(self, v: Visit) -> bool:
        start = asyncio.create_task(v.starts.get())
        gone = asyncio.create_task(v.gone.wait())
        done, pending = await asyncio.wait({start, gone}, timeout=START_WAIT,
                                           return_when=asyncio.FIRST_COMPLETED)  # fmt: skip
        for task in pending:
            task.cancel()
        if start in done:
            return True
        with contextlib.suppress(Exception):
            await v.ws.close()
        return False

    async def _session(self, v: Visit, pid: str, index: int, spec: SessionSpec) -> dict[str, Any]:
        """Run one session in its own process; relay until it ends. Returns its end."""
        folder = self.out / pid
        folder.mkdir(parents=True, exist_ok=True)
        log = folder / spec.log_name(index)
        here, there = self.ctx.Pipe()
        from strol_gym.benchmarks.serve import worker

        proc = self.ctx.Process(
            target=worker.run,
            args=(there, dataclasses.asdict(spec), str(log), self.fps),
            daemon=True,
        )
        await asyncio.to_thread(proc.start)  # blocks until the fork server has forked it
        there.close()
        loop = asyncio.get_running_loop()
        box: dict[str, Any] = {"frame": None, "texts": [], "end": None}
        wake = asyncio.Event()

        def deliver(message: tuple) -> None:
            if message[0] == "frame":  # only the newest frame waits: a slow page skips some
                box["frame"] = message
            elif message[0] in ("end", "error", "gone"):
                box["end"] = message
            else:
                box["texts"].append(message[1])
            wake.set()

        def pump() -> None:
            while True:
                try:
                    message = here.recv()
                except (EOFError, OSError):
                    loop.call_soon_threadsafe(deliver, ("gone", None))
                    return
                loop.call_soon_threadsafe(deliver, message)
                if message[0] in ("end", "error"):
                    return

        threading.Thread(target=pump, daemon=True).start()
        v.conn = here
        if v.gone.is_set():
            here.send(("stop", v.why_gone))
        try:
            while box["end"] is None:
                await wake.wait()
                wake.clear()
                texts, box["texts"] = box["texts"], []
                for panel in texts:
                    await self._send(v, {"t": "panel", **panel})
                frame, box["frame"] = box["frame"], None
                if frame is not None:
                    await self._send(v, frame[1].to_bytes(4, "big") + frame[2])
        finally:
            v.conn = None
            await asyncio.to_thread(proc.join, STOP_WAIT)
            if proc.is_alive():
                proc.kill()
            here.close()
        kind, body = box["end"]
        if kind == "end":
            keep = ("reason", "corrections", "real_time_factor", "frames", "cpu_share")
            end = {k: body[k] for k in keep}
        else:
            why = f"failed: {body}" if kind == "error" else "the session's process died"
            end = {"reason": why, "corrections": 0, "real_time_factor": None, "frames": 0,
                   "cpu_share": None}  # fmt: skip
        where = str(log.relative_to(self.out))
        self.participants.record(pid, spec, where, end["reason"], end["corrections"])
        return end


@contextlib.contextmanager
def serve_in_thread(server: Server, host: str = "127.0.0.1") -> Iterator[str]:
    """Run ``server`` with uvicorn in a thread of this process on a free port of ``host``;
    yields its base URL (``http://127.0.0.1:PORT``). For tests and the load benchmark."""
    import socket

    import uvicorn

    with socket.socket() as s:
        s.bind((host, 0))
        port = s.getsockname()[1]
    config = uvicorn.Config(
        server.app, host=host, port=port, ws_max_size=WS_MAX_SIZE, log_level="warning"
    )
    web = uvicorn.Server(config)
    thread = threading.Thread(target=web.run, daemon=True)
    thread.start()
    while not web.started:
        if not thread.is_alive():
            raise RuntimeError(f"the server did not start on {host}:{port}")
        time.sleep(0.05)
    try:
        yield f"http://{host}:{port}"
    finally:
        web.should_exit = True
        thread.join(timeout=30)


def _nothing() -> None:
    """A process that only starts the fork server."""


def _next(index: int, spec: SessionSpec) -> dict[str, Any]:
    help_lines = keymap.ARM_KEY_HELP if spec.kind == "arm" else keymap.CAR_KEY_HELP
    return {
        "t": "next",
        "index": index,
        "label": spec.label,
        "kind": spec.kind,
        "practice": spec.practice,
        "duration": spec.duration,
        "keys": list(help_lines),
    }


__all__ = ["PAGE_FILES", "Server"]
