"""The node's process: ROS started, the node (or the managed node) spun until a signal, ROS stopped.

What ``ros2 run physics_mapper node`` and ``physics-mapper node`` run (:mod:`physics_mapper.commands.node`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from physics_mapper.model.errors import EXIT_BAD_INPUT, InputError
from physics_mapper.model.scene_files import SceneError
from physics_mapper.ros.managed_node import ManagedPhysicsMapperNode
from physics_mapper.ros.node import PhysicsMapperNode
from physics_mapper.ros.spinning import STOP_POLL, SignalStop, shutdown_ros


def main(args: Sequence[str] | None = None, *, managed: bool = False) -> int:
    """Run the node (``managed``: the lifecycle node) until SIGINT or SIGTERM (exit 0); bad scene or
    parameters: one error line, exit 2."""
    stop = SignalStop()
    stop.install()  # rclpy installs none: see physics_mapper.ros.spinning
    try:
        rclpy.init(args=list(sys.argv if args is None else args), signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as error:  # rclpy's RCLError: malformed --ros-args, unreadable --params-file
        reason = str(error).split(" Error: ")[0].removeprefix("failed to initialize rcl: ")
        print(f"physics_mapper node: error: {reason}", file=sys.stderr)
        return EXIT_BAD_INPUT
    node = None
    try:
        if stop.requested:  # a signal during start-up: no node to start
            return 0
        node = ManagedPhysicsMapperNode(stop=stop) if managed else PhysicsMapperNode(stop=stop)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.requested:
            executor.spin_once(timeout_sec=STOP_POLL)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (SceneError, InputError, ParameterException) as error:
        print(f"physics_mapper node: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    finally:
        if node is not None:
            node.destroy_node()
        shutdown_ros()
    return 0
