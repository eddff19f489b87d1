"""``physics-mapper demo``: start the node, feed it a problem, print the map it publishes, stop it.

What ``make demo`` runs. The node is a child process, started as a launch file would;
this process feeds it (:func:`start_feed`) and listens to ``~/configuration`` and
``/diagnostics``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

from physics_mapper.cli import EXIT_FAILURE, InputError
from physics_mapper.scene import Problem, load_problem, load_scene

if TYPE_CHECKING:
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseArray
    from rclpy.node import Node

HELP = "start the node on a scene, publish a problem's hypotheses into it, print the map it publishes, stop it"
#: Rounds of hypotheses per second while the demo waits for the map.
FEED_RATE_HZ = 2.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scene", type=Path, default=Path("config/scenes/pyramid.yaml"), help="scene the node loads")
    parser.add_argument(
        "--problem", type=Path, default=Path("config/problems/pyramid.yaml"), help="hypotheses to publish"
    )
    parser.add_argument("--timeout", type=float, default=30.0, metavar="SECONDS", help="give up after (default 30)")


def start_feed(node: Node, problem: Problem) -> None:
    """Publish the problem's hypotheses at :data:`FEED_RATE_HZ` from ``node``'s executor."""
    from physics_mapper.problem_publisher import ProblemPublisher

    publisher = ProblemPublisher(node, problem)
    node.create_timer(1.0 / FEED_RATE_HZ, publisher.publish)


def _print_map(configuration: PoseArray, diagnostics: DiagnosticArray | None, names: tuple[str, ...]) -> None:
    print(f"configuration on ~/configuration (frame {configuration.header.frame_id!r}):")
    for name, pose in zip(names, configuration.poses, strict=True):
        p, q = pose.position, pose.orientation
        print(
            f"  {name:<14} position [{p.x:+.4f}, {p.y:+.4f}, {p.z:+.4f}] m  "
            f"orientation [{q.x:.4f}, {q.y:.4f}, {q.z:.4f}, {q.w:.4f}]"
        )
    if diagnostics is None:
        return
    search = diagnostics.status[0]
    print(f"diagnostics: {search.message}")
    for value in search.values:
        print(f"  {value.key}: {value.value}")


def _listen(
    problem: Problem, process: subprocess.Popen[str], timeout: float
) -> tuple[PoseArray | None, DiagnosticArray | None]:
    """Feed the node and wait for its first configuration and the diagnostics of that tick."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseArray
    from rclpy.utilities import ok

    from physics_mapper.ros_interface import (
        CONFIGURATION_TOPIC,
        DIAGNOSTICS_QOS,
        DIAGNOSTICS_TOPIC,
        MAP_QOS,
        NODE_NAME,
        output_topic,
        shutdown_ros,
    )

    configuration: list[PoseArray] = []
    diagnostics: list[DiagnosticArray] = []

    def on_diagnostics(msg: DiagnosticArray) -> None:
        if configuration and msg.status and msg.status[0].name == f"{NODE_NAME}: search":
            diagnostics.append(msg)

    rclpy.init()
    try:
        node = rclpy.create_node("physics_mapper_demo")
        node.create_subscription(PoseArray, output_topic(CONFIGURATION_TOPIC), configuration.append, MAP_QOS)
        node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, on_diagnostics, DIAGNOSTICS_QOS)
        start_feed(node, problem)
        end = time.monotonic() + timeout
        while ok() and not diagnostics and time.monotonic() < end and process.poll() is None:
            rclpy.spin_once(node, timeout_sec=0.1)
        node.destroy_node()  # type: ignore[no-untyped-call]
    finally:
        shutdown_ros()
    return (configuration[0] if configuration else None), (diagnostics[0] if diagnostics else None)


def run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    problem = load_problem(args.problem)
    if problem.scene.object_names != scene.object_names:
        raise InputError(
            f"{args.problem} has objects {', '.join(problem.scene.object_names)}; "
            f"the scene {args.scene} has {', '.join(scene.object_names)}"
        )
    from physics_mapper.launch import start_node, stop_node

    print(f"starting the node on {args.scene}, publishing {args.problem} at {FEED_RATE_HZ:g} Hz", flush=True)
    with tempfile.TemporaryFile(mode="w+") as log:
        process = start_node(args.scene.resolve(), output=log)
        try:
            configuration, diagnostics = _listen(problem, process, args.timeout)
        finally:
            exit_code = stop_node(process)
        if configuration is None:
            log.seek(0)
            print(f"no configuration within {args.timeout:g} s; node output:\n{log.read()}", file=sys.stderr)
            return EXIT_FAILURE
    _print_map(configuration, diagnostics, scene.object_names)
    print(f"node stopped (exit code {exit_code})")
    return 0 if exit_code == 0 else EXIT_FAILURE
