"""``physics-mapper node``: the ROS 2 node, for machines without ``ros2 run``."""

from __future__ import annotations

import argparse
import sys

HELP = "run the ROS 2 node (what `ros2 run physics_mapper node` runs); ROS arguments follow --ros-args"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--ros-args",
        dest="ros_args",
        nargs=argparse.REMAINDER,
        default=[],
        metavar="ARG",
        help="ROS arguments, e.g. --ros-args -p scene_file:=config/scenes/pyramid.yaml --params-file FILE",
    )


def run(args: argparse.Namespace) -> int:
    from physics_mapper.ros.node import main

    return main([sys.argv[0], "--ros-args", *args.ros_args])
