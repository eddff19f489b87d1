"""``physics-mapper node``: the ROS 2 node, for machines without ``ros2 run``; and ``ros2 run``'s scripts.

``ros2 run physics_mapper node`` starts the node, ticking from its start;
``ros2 run physics_mapper managed_node`` (``physics-mapper node --managed`` here) the lifecycle node,
which waits unconfigured for ``ros2 lifecycle set <node> configure`` and ``activate``.
"""

from __future__ import annotations

import argparse
import signal
import sys

HELP = "run the ROS 2 node (what `ros2 run physics_mapper node` runs); ROS arguments follow --ros-args"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--managed",
        action="store_true",
        help="run the lifecycle node (what `ros2 run physics_mapper managed_node` runs): unconfigured until told",
    )
    parser.add_argument(
        "--ros-args",
        dest="ros_args",
        nargs=argparse.REMAINDER,
        default=[],
        metavar="ARG",
        help="ROS arguments, e.g. --ros-args -p scene_file:=config/scenes/pyramid.yaml --params-file FILE",
    )


def hold_stop_signals() -> None:
    """Keep SIGINT and SIGTERM pending until the node handles them (``physics_mapper.ros.spinning.SignalStop``).

    Called first thing, before the node's imports: a KeyboardInterrupt raised in the middle of
    an import can be lost, or make CPython exit by SIGINT after all (see
    ``physics_mapper.ros.spinning``); a held signal is acted on once the node handles signals.
    """
    signal.pthread_sigmask(signal.SIG_BLOCK, (signal.SIGINT, signal.SIGTERM))


def run(args: argparse.Namespace) -> int:
    from physics_mapper.ros.run_node import main

    return main([sys.argv[0], "--ros-args", *args.ros_args], managed=args.managed)


def main() -> int:
    """``ros2 run physics_mapper node`` (setup.py's ``node`` script): the node with its arguments as given."""
    hold_stop_signals()
    from physics_mapper.ros.run_node import main as run_node

    return run_node(sys.argv)


def main_managed() -> int:
    """``ros2 run physics_mapper managed_node`` (setup.py's ``managed_node`` script): the lifecycle node."""
    hold_stop_signals()
    from physics_mapper.ros.run_node import main as run_node

    return run_node(sys.argv, managed=True)
