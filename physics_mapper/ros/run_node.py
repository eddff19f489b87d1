"""The node's process: ROS started, the node (or the managed node) spun until a signal, ROS stopped.

What ``ros2 run physics_mapper node`` and ``physics-mapper node`` run (:mod:`physics_mapper.commands.node`).
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
from collections.abc import Sequence

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from physics_mapper.model.errors import EXIT_BAD_INPUT, InputError
from physics_mapper.model.limits import printable
from physics_mapper.model.scene_files import SceneError
from physics_mapper.ros.managed_node import ManagedPhysicsMapperNode
from physics_mapper.ros.node import MapperNodeBase, PhysicsMapperNode
from physics_mapper.ros.spinning import STOP_POLL, SignalStop, shutdown_ros

#: Largest total size of the ``--params-file`` files, bytes. rcl parses them while it holds SIGINT and
#: SIGTERM, in time growing with the square of the size: 64 KiB in 0.03 s, 256 KiB in 0.8 s, 1.8 MB in
#: 14.6 s (``BENCHMARKS.md``, "Hostile inputs"); a whole robot's parameters take a few tens of kB.
MAX_PARAMS_FILE_BYTES = 128 * 1024
#: How rclpy reports a node it cannot create (a node name or namespace rcl refuses: longer than 255
#: characters, or malformed), as the start of its RCLError's text.
_NODE_NOT_CREATED = "error creating node: "
#: How rclpy refuses to declare an override whose value has no type (``frames: []``: an empty list).
_UNTYPED_OVERRIDE = "PARAMETER_NOT_SET"


def main(args: Sequence[str] | None = None, *, managed: bool = False) -> int:
    """Run the node (``managed``: the lifecycle node) until SIGINT or SIGTERM (exit 0); bad scene,
    parameters, params files, node name or namespace: one error line, exit 2."""
    arguments = list(sys.argv if args is None else args)
    stop = SignalStop()
    stop.install()  # rclpy installs none: see physics_mapper.ros.spinning
    try:
        check_params_files(arguments)
        rclpy.init(args=arguments, signal_handler_options=SignalHandlerOptions.NO)
    except InputError as error:
        return _refuse(str(error))
    except RuntimeError as error:  # rclpy's RCLError: malformed --ros-args, unreadable --params-file
        return _refuse(str(error).split(" Error: ")[0].removeprefix("failed to initialize rcl: "))
    node = None
    try:
        if stop.requested:  # a signal during start-up: no node to start
            return 0
        node = _create_node(managed, stop)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.requested:
            executor.spin_once(timeout_sec=STOP_POLL)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (SceneError, InputError, ParameterException) as error:
        return _refuse(str(error))
    finally:
        if node is not None:
            node.destroy_node()
        shutdown_ros()
    return 0


def _refuse(reason: str) -> int:
    """One error line (input text in it escaped), exit 2."""
    print(f"physics_mapper node: error: {printable(reason)}", file=sys.stderr)
    return EXIT_BAD_INPUT


def check_params_files(arguments: Sequence[str]) -> None:
    """Refuse (InputError) ``--params-file`` files larger than :data:`MAX_PARAMS_FILE_BYTES` in all, before
    rcl parses them (a missing or unreadable one is left for rcl to report)."""
    paths = [arguments[i + 1] for i, argument in enumerate(arguments[:-1]) if argument == "--params-file"]
    sizes = {}
    for path in paths:
        with contextlib.suppress(OSError):
            sizes[path] = os.stat(path).st_size
    if sum(sizes.values()) > MAX_PARAMS_FILE_BYTES:
        listed = ", ".join(f"{path} ({size} bytes)" for path, size in sizes.items())
        raise InputError(f"--params-file: {listed}: more than {MAX_PARAMS_FILE_BYTES} bytes in all")


def _create_node(managed: bool, stop: SignalStop) -> MapperNodeBase:
    """The node, or InputError for what rclpy refuses to make of the arguments (a name, an override)."""
    try:
        # rclpy warns of what it cannot clean up after a failed rcl_node_init; the error line says it all.
        with warnings.catch_warnings(record=True) as caught:
            node = ManagedPhysicsMapperNode(stop=stop) if managed else PhysicsMapperNode(stop=stop)
        for warning in caught:
            warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)
        return node
    except RuntimeError as error:  # rclpy's RCLError from rcl_node_init
        text = str(error)
        if not text.startswith(_NODE_NOT_CREATED):
            raise
        reason = text.removeprefix(_NODE_NOT_CREATED).split(", at ")[0]
        raise InputError(f"cannot create the node: {reason} (names are at most 255 characters)") from None
    except ValueError as error:  # rclpy declaring every override (see MapperNodeBase)
        if _UNTYPED_OVERRIDE not in str(error):
            raise
        raise InputError(
            "a parameter from --params-file or -p has a value without a type, an empty list ([]): "
            "ROS cannot declare it; remove it or give the list an element"
        ) from None
