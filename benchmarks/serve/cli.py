"""``strol-bench serve``: a study anyone can join from a browser (the ``[serve]`` extra)."""

from __future__ import annotations

import ipaddress
import math
import secrets
from pathlib import Path
from typing import Any

NEEDS_EXTRA = 'strol-bench serve needs the [serve] extra: pip install "strol-gym[serve]"'


def add_parser(sub: Any) -> None:
    from strol_gym.benchmarks.args import positive_int

    p = sub.add_parser(
        "serve",
        help="a study in the browser: people push the arm and correct the car from a web page",
        description="Serve a page where a person pushes the study arm's cup (Tasks 1-3) and "
        "corrects the Highway's car from the keyboard or a gamepad, one env per visitor on this "
        "machine at real time. Without --study each visitor does a short practice on the arm "
        "and the car; with --study PLAN (a JSON file, docs/serve.md) each gets an anonymous id, "
        "the researcher's information page and a counterbalanced order of learners and Tasks. "
        "Every session is logged under --out (strol-bench replay reads it); --export writes the "
        "study as Minari datasets. The link printed carries a token every visitor needs.",
    )
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (127.0.0.1)")
    p.add_argument("--port", type=positive_int("--port", 65_535, low=1), default=8000)
    p.add_argument("--study", default=None, help="a study plan (JSON); default: practice only")
    p.add_argument("--out", default="sessions/serve", help="folder of the logs (sessions/serve)")
    p.add_argument("--fps", type=float, default=8.0, help="the arm's frames a second (1-30; 8)")
    p.add_argument(
        "--max-participants",
        type=positive_int("--max-participants", 64, low=1),
        default=4,
        help="visitors served at once (4); more are asked to come back",
    )
    p.add_argument(
        "--export",
        action="store_true",
        help="write the study in --out as Minari datasets (one per Task and learner, under the "
        "plan's name as namespace), then exit",
    )


def check_host(host: str) -> bool:
    """Whether ``host`` is a loopback address; ValueError if it is no address."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        raise ValueError(f"--host must be an IP address (e.g. 127.0.0.1), got {host!r}") from None


def command(args: Any, parser: Any) -> int:
    from strol_gym.benchmarks.serve.plan import load_plan

    if not math.isfinite(args.fps) or not 1.0 <= args.fps <= 30.0:
        raise ValueError(f"--fps must be in [1, 30], got {args.fps}")
    loopback = check_host(args.host)
    plan = load_plan(args.study)
    out = Path(args.out)
    if args.export:
        from strol_gym.benchmarks.serve.export import export_study

        for dataset_id, n in export_study(out, plan):
            print(f"wrote Minari dataset {dataset_id}: {n} session(s)")
        return 0
    try:
        import uvicorn

        from strol_gym.benchmarks.serve.app import WS_MAX_SIZE, Server
    except ImportError:
        raise ValueError(NEEDS_EXTRA) from None
    token = secrets.token_urlsafe(16)
    server = Server(plan, out, token, fps=args.fps, max_visits=args.max_participants)
    shown = f"[{args.host}]" if ":" in args.host else args.host
    print(f"study {plan.name!r}: logs in {out}/")
    print(f"the link to send: http://{shown}:{args.port}/?token={token}")
    if not loopback:
        print("listening beyond this machine: only people with the link (its token) get in")
    uvicorn.run(
        server.app,
        host=args.host,
        port=args.port,
        ws_max_size=WS_MAX_SIZE,
        log_level="warning",
    )
    return 0


__all__ = ["add_parser", "check_host", "command"]
