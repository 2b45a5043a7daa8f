"""``strol-bench interact``'s command line: a person at the study arm (``interact [arm]``) or at
the Highway car (``interact car``, or ``--env highway``). Argument parsing only, so ``--help``
imports nothing heavy; the sessions live in ``interact`` (the arm) and ``drive`` (the car)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

ARM_HELP = (
    "Push the study arm yourself in MuJoCo's viewer; the robot learns from your corrections. "
    "The env is the one strol-bench study runs (its Task and learner, no simulated user). "
    "PUSH with the keys: W/S (or Up/Down) away from / towards you, A/D (or Left/Right) left / "
    "right, E/Q (or Page Up/Down) up / down, and on Tasks 2-3 I/K tilt, J/L turn, U/O roll the "
    "cup; a key push grows like a hand's to 40 N and stays below the arm's 100 N reflex unless "
    "you hold Shift (harder: the arm brakes). Or with the MOUSE: the cup is selected at the "
    "start (double-click a link to select another; Home selects the cup again), Ctrl + "
    "right-drag pushes it with a force that grows with the drag's length (10 cm = 40 N). Or "
    "with a GAMEPAD (--gamepad): left stick, RB/LB up/down, right stick tilt/turn, RT "
    "harder. A push above 15 N is a correction "
    "(above the reflex, or on v2 sooner where a joint cannot bear the push, the arm brakes and "
    "nothing counts); the learner updates and the robot replans. F8: the plan for theta*; F9: "
    "hide or show the panel. END: close the window, or Ctrl-C / SIGTERM (exit status 130); "
    "the session also ends when --duration simulated seconds are up. LOG: every correction, "
    "reflex and selection, and an end line with the reason, steps and simulated time, in "
    "--log (default sessions/session-TIME.jsonl); strol-bench replay reads it. Without a "
    "display: xvfb-run -a strol-bench interact."
)
CAR_HELP = (
    "Drive the blue (human) car on the Highway yourself in highway-env's window; the green "
    "robot car learns from your corrections. KEYS: Up/Down (or W/S) accelerate/brake, "
    "Left/Right (or A/D) steer; holding a key for the whole 0.5 s step is the full a_max, no "
    "key no correction. Or a GAMEPAD (--gamepad): left stick steers, RT/LT accelerate/brake. "
    "F9: hide or show the panel. END: close the window, or Ctrl-C / SIGTERM (exit status "
    "130); the session also ends when --duration simulated seconds are up, or when the cars "
    "collide (the panel and the console say so). LOG: every correction and an end line with "
    "the reason, steps and simulated time, in --log (default sessions/session-TIME.jsonl); "
    "strol-bench replay reads it. Without a display: xvfb-run -a strol-bench interact car."
)
MODES = {"arm": "robot", "robot": "robot", "car": "highway", "highway": "highway"}
"""The positional mode's words -> ``--env``'s."""


class _ModeHelp(argparse.Action):
    """``--help`` that describes the mode named before it (``interact car --help``,
    ``interact --env highway --help``)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="show this mode's help and exit")

    def __call__(self, parser: Any, namespace: Any, values: Any, option: Any = None) -> None:
        mode = MODES.get(getattr(namespace, "mode", None) or "", "")
        env = mode or getattr(namespace, "env", "robot")
        parser.description = CAR_HELP if env == "highway" else ARM_HELP
        parser.print_help()
        parser.exit()


def add_parser(sub: Any) -> None:
    from strol_gym.benchmarks.args import plugin_option

    p = sub.add_parser(
        "interact",
        help="push the study arm (or drive the Highway car) yourself; the robot learns "
        "(needs a display)",
        description=ARM_HELP + " Drive the Highway car instead: strol-bench interact car.",
        add_help=False,
    )
    p.add_argument("-h", "--help", action=_ModeHelp)
    p.add_argument(
        "mode",
        nargs="?",
        default=None,
        choices=sorted(MODES),
        help="arm (the study arm, default) or car (the Highway car); the same as --env",
    )
    p.add_argument(
        "--env",
        default="robot",
        help="robot (push the study arm in MuJoCo's viewer, default) or highway (drive the "
        "human car in highway-env's window)",
    )
    p.add_argument("--task", default="1", help="study Task: 1, 2 or 3 (default 1; arm only)")
    p.add_argument("--learner", default="strol", help="registered name or module:attr (strol)")
    p.add_argument("--learner-kwargs", default=None, help="JSON, e.g. '{\"lam\": 0.5}'")
    p.add_argument("--seed", type=int, default=20000, help="θ̂0's seed (default 20000)")
    p.add_argument("--log", default=None, help="session log (default sessions/session-TIME.jsonl)")
    p.add_argument(
        "--duration", type=float, default=120.0, help="simulated seconds until time is up (120)"
    )
    p.add_argument("--max-steps", type=int, default=None, help="stop after N control steps")
    p.add_argument(
        "--fast",
        action="store_true",
        help="do not pace the steps to wall-clock time (faster than real time where the "
        "machine allows: for tests and demos)",
    )
    p.add_argument(
        "--gamepad",
        action="store_true",
        help="also read the first gamepad (SDL's game controllers, through pygame)",
    )
    p.add_argument(
        "--blind",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="hide theta_hat and phi from the panel (default: a participant never sees them; "
        "the log keeps them); --no-blind for the experimenter",
    )
    plugin_option(p)


def command(args: Any, parser: Any) -> int:
    from strol_gym.benchmarks.args import check_learner_names
    from strol_gym.envs.panda.model import has_display

    if args.mode is not None:
        env = MODES[args.mode]
        if args.env not in ("robot", env):
            raise ValueError(f"interact {args.mode} and --env {args.env} disagree; give one")
        args.env = env
    if args.task not in ("1", "2", "3"):
        raise ValueError(f"--task must be 1, 2 or 3, got {args.task!r}")
    check_learner_names([args.learner])
    kwargs = None
    if args.learner_kwargs:
        try:
            kwargs = json.loads(args.learner_kwargs)
        except (ValueError, RecursionError) as e:
            raise ValueError(f"--learner-kwargs must be a JSON object ({e})") from None
        if not isinstance(kwargs, dict):
            raise ValueError("--learner-kwargs must be a JSON object, e.g. '{\"lam\": 0.5}'")
    if args.max_steps is not None and args.max_steps < 1:
        raise ValueError(f"--max-steps must be an integer >= 1, got {args.max_steps}")
    if not math.isfinite(args.duration) or not 0 < args.duration <= 86_400:
        raise ValueError(f"--duration must be in (0, 86400] simulated seconds, got {args.duration}")
    if args.log is not None and Path(args.log).exists():
        raise ValueError(f"--log {args.log} exists; sessions are never overwritten")
    if args.env not in ("robot", "highway"):
        raise ValueError(f"--env must be robot or highway, got {args.env!r}")
    pad = None
    if args.env == "highway":
        from strol_gym.benchmarks.sessions.drive import NO_DISPLAY_HIGHWAY, run_drive

        if not has_display():
            raise ValueError(NO_DISPLAY_HIGHWAY)
        if args.gamepad:
            from strol_gym.benchmarks.sessions.gamepad import first_gamepad

            pad = first_gamepad()
        duration = args.duration if args.max_steps is None else args.max_steps * 0.5
        path, info = run_drive(
            learner=args.learner,
            learner_kwargs=kwargs,
            seed=args.seed,
            log=args.log,
            duration=duration,
            realtime=not args.fast,
            blind=args.blind,
            pad=pad,
        )
        return summary(path, info)
    from strol_gym.benchmarks.sessions.interact import NO_DISPLAY, run_interactive

    if not has_display():  # after the arguments, before anything is built
        raise ValueError(NO_DISPLAY)
    if args.gamepad:
        from strol_gym.benchmarks.sessions.gamepad import first_gamepad

        pad = first_gamepad()
    path, info = run_interactive(
        task=int(args.task),
        learner=args.learner,
        learner_kwargs=kwargs,
        seed=args.seed,
        log=args.log,
        duration=args.duration,
        max_steps=args.max_steps,
        realtime=not args.fast,
        blind=args.blind,
        pad=pad,
    )
    return summary(path, info)


def summary(path: Path, info: dict[str, Any]) -> int:
    """The session's last lines on the terminal: how it ended, corrections and reflexes, θ̂;
    130 after Ctrl-C or SIGTERM."""
    from strol_gym.benchmarks.sessions.person import ended_words

    print(ended_words(info.get("end_reason", ""), float(info.get("time", 0.0))))
    print(f"real-time factor {info['real_time_factor']:.2f} (simulated s per wall-clock s)")
    if "theta_hat" in info:
        theta = ", ".join(f"{t:+.3f}" for t in info["theta_hat"])
        pushing = info.get("correction_time")
        reflexes = info.get("reflexes")
        print(
            f"{info['corrections']} correction(s)"
            + ("" if pushing is None else f", {pushing:.2f} s of pushing")
            + ("" if reflexes is None else f", {reflexes} reflex(es): pushes too hard to count")
        )
        print(f"final θ̂ = ({theta}); session log: {path}")
    print(f"replay it: strol-bench replay {path} --learners strol,gradient")
    if info.get("interrupted"):
        print(f"interrupted: the session ended and its log is complete ({path})", file=sys.stderr)
        return 130
    return 0
