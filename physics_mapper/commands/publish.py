"""``physics-mapper publish``: publish a problem file's hypotheses and weights to the node."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from physics_mapper.commands.files import input_file, load_problem_file
from physics_mapper.model.errors import InputError
from physics_mapper.model.limits import MAX_QUOTED_TEXT, clipped

if TYPE_CHECKING:
    from physics_mapper.model.scene import Problem

#: Seconds to keep the process alive after the last round, so that it is delivered.
LINGER = 0.3
#: Seconds between seeing the node's subscriptions and the first round (see :func:`_publish`).
DISCOVERY_SETTLE = 0.3

HELP = "publish a problem file's hypotheses and weights on the node's input topics (like `ros2 topic pub`)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("problem", type=input_file, help="problem YAML: a scene plus hypotheses per object")
    parser.add_argument("--rate", type=float, default=1.0, metavar="HZ", help="rounds per second (default 1)")
    parser.add_argument("--count", type=int, default=0, metavar="N", help="rounds to publish; 0 = until Ctrl-C")
    parser.add_argument("--namespace", default="", metavar="NS", help="namespace of the node's topics (default: /)")
    parser.add_argument(
        "--wait",
        type=float,
        default=5.0,
        metavar="SECONDS",
        help="wait this long for the node's subscriptions before the first round (default 5)",
    )


def run(args: argparse.Namespace) -> int:
    if not args.rate > 0.0:
        raise InputError(f"--rate must be positive, got {args.rate:g}")
    if args.count < 0:
        raise InputError(f"--count must not be negative, got {args.count}")
    problem = load_problem_file(args.problem, "publish")

    from rclpy.exceptions import InvalidNamespaceException
    from rclpy.validate_namespace import validate_namespace

    from physics_mapper.ros.spinning import ros_for_command

    namespace = "/" + args.namespace.lstrip("/")
    try:
        validate_namespace(namespace)
    except InvalidNamespaceException:
        shown = clipped(args.namespace, MAX_QUOTED_TEXT)
        raise InputError(f"--namespace {shown!r} is not a valid ROS namespace") from None
    try:
        with ros_for_command():
            _publish(args, problem, namespace)
    except KeyboardInterrupt:
        pass
    return 0


def _publish(args: argparse.Namespace, problem: Problem, namespace: str) -> None:
    """Publish ``problem``'s hypotheses ``args.count`` times (0: until stopped) at ``args.rate``."""
    import rclpy
    from rclpy.utilities import ok

    from physics_mapper.ros.hypothesis_publisher import HypothesisPublisher
    from physics_mapper.ros.spinning import spin_for, spin_once

    node = rclpy.create_node("physics_mapper_publisher", namespace=namespace)
    publisher = HypothesisPublisher(node, problem)
    sizes = ", ".join(f"{n} ({len(h)})" for n, h in zip(problem.scene.object_names, problem.hypotheses, strict=True))
    print(f"publishing {sizes} on {node.get_namespace().rstrip('/')}/hypotheses/<object>[/weights]", flush=True)
    if publisher.wait_for_subscribers(args.wait):
        # The subscriber side matches this new publisher a moment after this side sees it;
        # a message published before then is lost.
        spin_for(node, DISCOVERY_SETTLE)
    elif ok():
        print(f"no subscriber on every topic after {args.wait:g} s; publishing anyway", flush=True)
    rounds = 0

    def publish_round() -> None:
        nonlocal rounds
        if args.count == 0 or rounds < args.count:
            publisher.publish()
            rounds += 1

    publish_round()
    node.create_timer(1.0 / args.rate, publish_round)
    while ok() and (args.count == 0 or rounds < args.count):
        spin_once(node, 0.1)
    spin_for(node, LINGER)  # reliable delivery of the last round completes in the background
    print(f"published {rounds} round{'s' if rounds != 1 else ''}", flush=True)
    node.destroy_node()  # type: ignore[no-untyped-call]
