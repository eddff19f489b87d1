"""``physics-mapper``: one entry point, one module per subcommand of :mod:`physics_mapper.commands`.

Each subcommand module has ``HELP``, ``add_arguments`` and ``run``, and imports ROS and matplotlib
inside ``run``, so that ``--help`` and the ROS-free commands start fast and work without rclpy.

Exit codes: 0 success, 1 a run-time failure, 2 bad arguments or input files, 3 a report written
without some of its bags (``evaluate``, ``sweep``); a command stopped by SIGINT or SIGTERM exits
130, except those meant to run until stopped (the node, ``publish``), which exit 0. From the
first line run here on, SIGTERM stops like Ctrl-C; for the node both are held pending until it
handles them (``physics_mapper.commands.node.hold_stop_signals``). Heavy imports come after.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
from collections.abc import Sequence
from types import ModuleType

from physics_mapper.commands.node import hold_stop_signals

#: Subcommand names, each a module of :mod:`physics_mapper.commands`, in the order ``--help`` lists them.
COMMANDS = (
    "solve",
    "generate",
    "replay",
    "evaluate",
    "sweep",
    "node",
    "publish",
    "demo",
    "experiment",
    "bench",
    "decompose",
)
#: Commands that run until they are stopped: a signal is how they end, not an interruption.
RUN_UNTIL_STOPPED = ("node", "publish")
#: ``model.errors.EXIT_INTERRUPTED``, here without importing the model (numpy) before the signals are set up.
EXIT_INTERRUPTED = 130


def command_module(name: str) -> ModuleType:
    """The module of subcommand ``name``."""
    return importlib.import_module(f"physics_mapper.commands.{name}")


def _stop_on_sigterm_like_ctrl_c() -> None:
    """Until a command installs its own handlers, SIGTERM raises KeyboardInterrupt, as SIGINT does."""
    signal.signal(signal.SIGTERM, signal.default_int_handler)


def _abandon_stdout() -> None:
    """Point the standard output at /dev/null: what it still buffers would fail again at exit."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # no descriptor behind sys.stdout: nothing to flush at exit
        pass


def caused_by_interrupt(error: BaseException) -> bool:
    """Whether ``error`` is a KeyboardInterrupt, or was raised from one.

    CPython 3.11 re-raises what a descriptor's ``__set_name__`` raises as a RuntimeError from it: a
    Ctrl-C that lands while an import creates a dataclass arrives as that RuntimeError.
    """
    cause: BaseException | None = error
    while cause is not None:
        if isinstance(cause, KeyboardInterrupt):
            return True
        cause = cause.__cause__
    return False


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="physics-mapper",
        description="Physically consistent multi-object maps from weighted pose hypotheses (Wagle & Correll 2010).",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        module = command_module(name)
        sub = subparsers.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(sub)
        sub.set_defaults(run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    arguments = list(sys.argv[1:] if argv is None else argv)
    if arguments[:1] == ["node"]:
        hold_stop_signals()
    else:
        _stop_on_sigterm_like_ctrl_c()
    try:
        from physics_mapper.model.errors import EXIT_BAD_INPUT, InputError
        from physics_mapper.model.limits import printable
        from physics_mapper.model.scene_files import SceneError

        args = build_parser().parse_args(arguments)
        try:
            code = int(args.run(args))
            sys.stdout.flush()  # a full disk or a closed pipe shows here, not in the interpreter's exit
            return code
        except (SceneError, InputError) as error:
            print(f"physics-mapper {args.command}: error: {printable(str(error))}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except OSError as error:
            if error.filename is not None:  # a file's error, not the standard output's
                raise
            _abandon_stdout()
            print(
                f"physics-mapper {args.command}: error: cannot write to standard output: {error.strerror}",
                file=sys.stderr,
            )
            return EXIT_BAD_INPUT
    except (KeyboardInterrupt, RuntimeError) as error:
        if not caused_by_interrupt(error):
            raise
        return 0 if arguments[:1] and arguments[0] in RUN_UNTIL_STOPPED else EXIT_INTERRUPTED
