"""``strol-bench``: the experiments (``strol_gym.benchmarks.experiments``), training, the
interactive sessions, listings and reports.

Every argument is checked before any work starts: a bad one exits with status 2 and a message
naming the argument and its valid values (argparse's convention). An experiment registered by a
module given to ``--plugin`` is a subcommand like the built-in ones.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import os
import signal
import sys
import threading
from collections.abc import Sequence
from typing import Any

from strol_gym import limits
from strol_gym.benchmarks.args import RUNNER_CAPS, check_size_caps, plugin_option
from strol_gym.benchmarks.engine.conditions import ENV_PRESETS, make_condition
from strol_gym.benchmarks.engine.results import ResultsError
from strol_gym.benchmarks.experiments import EXPERIMENTS, make_experiment
from strol_gym.learners.protocol import LearnerFailed

OWN_COMMANDS: dict[str, str] = {
    "train": "train ĝ for StROL or e2e (Algorithm 1)",
    "list": "envs and every registry: learners, humans, Tasks, conditions",
    "replay": "feed a session log's corrections through learners (table, CSV, plot)",
    "export": "write a session log, or benchmark runs, as a Minari dataset (the [data] extra)",
    "interact": "push the study arm (or drive the Highway car) yourself; the robot learns "
    "(needs a display)",
    "import-study": "the authors' user-study pickles as session logs (replay them with replay)",
    "fit-human": "fit a human model to correction logs; compare models by held-out likelihood",
    "check-human": "posterior-predictive check of a simulated person against real session logs",
    "fit-timing": "fit when the study's people corrected, given the robot's plan; check on a "
    "held-out learner",
    "fit-participant": "fit the study population (StROL-Study-v2's participant) to imported "
    "study logs",
    "serve": "a study in the browser: people push the arm and correct the car from a web page",
    "report": "re-render tables, summary.md and plots from a folder",
}
"""The commands that are not experiments, with their one-line help: ``strol-bench --help``
lists them without importing their modules (tests/test_bench_cli.py checks each against the
help its own parser gives)."""


def _add_own_parser(sub: Any, name: str) -> None:
    """The full parser of one of :data:`OWN_COMMANDS` (this imports what the command needs)."""
    if name == "train":
        from strol_gym.benchmarks.train import add_train_arguments

        p = sub.add_parser("train", help=OWN_COMMANDS["train"])
        add_train_arguments(p)
        plugin_option(p)
    elif name == "list":
        p = sub.add_parser("list", help=OWN_COMMANDS["list"])
        plugin_option(p)
    elif name == "report":
        p = sub.add_parser("report", help=OWN_COMMANDS["report"])
        p.add_argument("folder", help="a results folder written by paper or run")
        p.add_argument("--no-plots", action="store_true")
        plugin_option(p)  # the run's own pieces: a user learner keeps its display name
    elif name == "serve":
        from strol_gym.benchmarks.serve import cli as serve

        serve.add_parser(sub)
    else:
        module = "interact_cli" if name == "interact" else name.replace("-", "_")
        importlib.import_module(f"strol_gym.benchmarks.sessions.{module}").add_parser(sub)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``strol-bench`` parser. Every experiment's parser is built (their modules are light);
    of :data:`OWN_COMMANDS` only ``command``'s (all of them when ``command`` is None), the
    others by name and one-line help, so that ``--help`` and ``list`` load neither torch nor
    MuJoCo."""
    parser = argparse.ArgumentParser(
        prog="strol-bench",
        description="Benchmark online reward learners on the StROL envs (paired runs, statistics, "
        "tables and plots).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in EXPERIMENTS.names():
        make_experiment(name).add_parser(sub)
    for name, summary in OWN_COMMANDS.items():
        if command is None or name == command:
            _add_own_parser(sub, name)
        else:
            sub.add_parser(name, help=summary, add_help=False)
    return parser


def _command(argv: Sequence[str]) -> str | None:
    """The command ``argv`` names (its first word that is not an option), or None."""
    return next((a for a in argv if not a.startswith("-")), None)


# ---------------------------------------------------------------------- commands
def cmd_list(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.registry import registries

    regs = registries()
    order = ["env", "learner", "human", "task", "condition"]  # then any other kind
    for kind in sorted(regs, key=lambda k: order.index(k) if k in order else len(order)):
        reg = regs[kind]
        user = set(reg.user_names())
        names = [f"{n} (yours)" if n in user else n for n in reg.names()]
        tail = "" if reg.decode is not None else " (or module:attr)"
        print(f"{kind}s: " + ", ".join(names) + tail)
    print("envs in detail:")
    for key, p in ENV_PRESETS.items():
        print(
            f"  {key:8s} {p.env_id}: {p.runs} runs, {p.n_corrections} corrections, "
            f"primary metric {p.primary_metric}"
        )
    print("humans in detail:")
    for name in regs["human"].names():
        print(f"  {name:14s} {human_summary(name)}")
    print("conditions in detail (the study's envs run the study's own: strol-bench study):")
    for key in (k for k, p in ENV_PRESETS.items() if p.paper_conditions):
        for name in registries()["condition"].names():
            c = make_condition(key, name)
            print(f"  {key:8s} {c.name:14s} {c.describe()}")
    return 0


def human_summary(name: str, width: int = 110) -> str:
    """The first sentence of a registered human's docstring (its model's), on one line."""
    import inspect
    import re

    from strol_gym.humans import HUMANS

    try:
        piece = HUMANS.get(name)
    except ValueError as e:  # a user's lazy entry that does not import
        return f"(cannot import: {e})"
    doc = " ".join((inspect.getdoc(getattr(piece, "model_class", piece)) or "").split())
    first = re.split(r"(?<!\beq\.)(?<=[.!?])\s", doc, maxsplit=1)[0].replace("``", "")
    return first if len(first) <= width else first[: width - 1] + "…"


def cmd_report(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.analysis.report import console_summary, write_reports
    from strol_gym.benchmarks.engine.results import ResultsDir

    rd = ResultsDir.load(args.folder)
    missing = rd.missing_units()
    if missing:
        print(f"note: {len(missing)} unit(s) of work are missing; the report covers finished runs")
    analysis, plots = write_reports(rd, plots=not args.no_plots)
    print(console_summary(analysis))
    print(f"summary: {rd.path / 'summary.md'}")
    for p in plots:
        if p.suffix == ".png":
            print(f"plot: {p}")
    return 0


def cmd_train(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.train import run_train

    run_train(args)
    return 0


def cmd_replay(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.sessions.replay import command

    return command(args, parser)


def cmd_export(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.sessions.export import command

    return command(args, parser)


def cmd_interact(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.sessions.interact_cli import command

    return command(args, parser)


def cmd_fit_human(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.sessions.fit_human import command

    return command(args, parser)


def cmd_check_human(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.sessions.check_human import command

    return command(args, parser)


def cmd_fit_participant(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.sessions.fit_participant import command

    return command(args, parser)


def cmd_fit_timing(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.sessions.fit_timing import command

    return command(args, parser)


def cmd_serve(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.serve.cli import command

    return command(args, parser)


def cmd_import_study(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from strol_gym.benchmarks.sessions.import_study import command

    return command(args, parser)


COMMANDS = {
    "fit-human": cmd_fit_human,
    "check-human": cmd_check_human,
    "fit-participant": cmd_fit_participant,
    "fit-timing": cmd_fit_timing,
    "import-study": cmd_import_study,
    "replay": cmd_replay,
    "interact": cmd_interact,
    "serve": cmd_serve,
    "export": cmd_export,
    "train": cmd_train,
    "list": cmd_list,
    "report": cmd_report,
}
"""The commands that are not experiments (those are found in ``EXPERIMENTS``)."""


def _import_plugins(argv: Sequence[str]) -> None:
    """Import every ``--plugin`` module named in ``argv`` before the parser is built, so the
    experiments they register are subcommands."""
    from strol_gym.registry import import_plugin, load_installed_plugins

    load_installed_plugins()  # installed packages' strol_gym.plugins entry points
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--plugin", action="append", default=[])
    for plugin in pre.parse_known_args(list(argv))[0].plugin:
        import_plugin(plugin)


INTERRUPTED = "interrupted: finished runs are saved; rerun the same command to resume"
INTERRUPTED_NO_RESUME = (
    "interrupted: nothing was saved ({command} keeps no partial state); rerun it to start over"
)
RESUMABLE = frozenset({"run", "paper", "lambda", "changing", "robustness", "confirm", "study"})
"""The commands that write a results folder and so resume after an interrupt."""


def _interrupted(args: argparse.Namespace) -> str:
    """What is true after an interrupt: a results folder resumes; other commands start over."""
    command = getattr(args, "command", "")
    if command in RESUMABLE or hasattr(args, "block"):
        return INTERRUPTED
    return INTERRUPTED_NO_RESUME.format(command=command)


def _interrupted_at_start(signum: int, frame: Any) -> None:
    """SIGINT before any work: nothing to save or release, so one line and status 130 at once
    (a KeyboardInterrupt inside an import can surface as another error, or a traceback)."""
    os.write(2, b"\ninterrupted\n")
    os._exit(130)


def _quiet_stdout() -> None:
    """After the reader of our output went away (``| head``): point stdout at the null device,
    so the interpreter's last flush at exit has nowhere to fail and prints nothing."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


BENCH_MODULES = ("matplotlib", "tqdm")
"""The import names of setup.cfg's ``[bench]`` extra (tables, plots, progress bars), which the
core install leaves out (tests/test_release.py checks they agree)."""


def missing_bench_extra() -> str | None:
    """None when the ``[bench]`` extra is installed, else the reason to print: checked before
    any command, so a core install gets one line naming the extra, not an ImportError mid-run."""
    missing = [m for m in BENCH_MODULES if importlib.util.find_spec(m) is None]
    if not missing:
        return None
    return (
        f"strol-bench needs the [bench] extra ({', '.join(missing)} not installed): "
        "pip install 'strol-gym[bench]'"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``strol-bench`` console script. Output piped into a reader that
    stops early (``strol-bench list | head``) ends quietly, with status 0: the output is flushed
    here, where a closed pipe can be caught, not at exit."""
    problem = missing_bench_extra()
    if problem:
        print(f"strol-bench: error: {problem}", file=sys.stderr)
        return 2
    caps_lifted = limits.lifted_now()
    try:
        try:
            status = _main(argv)
        finally:  # also for argparse's --help, which exits
            limits.lift(caps_lifted)  # --allow-large lifts the caps for its command only
            sys.stdout.flush()
    except BrokenPipeError:
        _quiet_stdout()
        return 0
    return status


def _main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    # Only where Ctrl-C would raise KeyboardInterrupt (not in another thread, nor where it is
    # ignored, as for a background job)
    watch = (
        threading.current_thread() is threading.main_thread()
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    )
    if watch:
        signal.signal(signal.SIGINT, _interrupted_at_start)
    try:
        try:
            _import_plugins(argv)
        except ValueError as e:  # as main's own handler below says it: exit status 2
            print(f"strol-bench: error: {e}", file=sys.stderr)
            raise SystemExit(2) from None
        # only the named command's parser in full: the others by name and help (an unknown
        # word still gets argparse's list of the valid choices)
        named = _command(argv)
        parser = build_parser(named if named in OWN_COMMANDS else "")
        args = parser.parse_args(argv)
    finally:  # from here on an interrupt is a KeyboardInterrupt: runs save what is finished
        if watch:
            signal.signal(signal.SIGINT, signal.default_int_handler)
    if getattr(args, "out", None) == "":  # would silently mean the default folder
        parser.error("--out must name a path, got an empty string")
    try:
        if hasattr(args, "block") and hasattr(args, "jobs"):  # a command that runs the runner
            check_size_caps(args, RUNNER_CAPS)
        command = COMMANDS.get(args.command) or make_experiment(args.command)
        return command(args, parser)
    except (ResultsError, LearnerFailed) as e:
        print(f"strol-bench: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader of our output left (| head): main ends quietly
        raise
    except (ValueError, OSError) as e:  # OSError: a path we cannot read or write (it is named)
        parser.exit(2, f"strol-bench: error: {e}\n")
    except MemoryError:  # input too large for this machine: said in one line, not a traceback
        parser.exit(2, f"strol-bench: error: {args.command}: out of memory (an input too large?)\n")
    except KeyboardInterrupt:
        print(f"\n{_interrupted(args)}", file=sys.stderr)
        return 130
    except ImportError as e:  # an interrupt inside a C extension's import surfaces as this
        if not isinstance(e.__context__, KeyboardInterrupt):
            raise
        print(f"\n{_interrupted(args)}", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
