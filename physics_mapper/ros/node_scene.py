"""The node's scene: its path from the ``scene_file`` parameter, and its load while the node spins.

A scene's first load may decompose meshes (a minute for CoACD): the load runs in a thread
(:class:`~physics_mapper.model.scene_loading.SceneLoading`) while the node spins, and the node
reports on ``/diagnostics`` what it is doing. A signal stops the load at once.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from physics_mapper.mapping.topics import DIAGNOSTICS_TOPIC
from physics_mapper.model.errors import InputError
from physics_mapper.model.limits import MAX_DIAGNOSTIC_TEXT, clipped, printable
from physics_mapper.model.resources import ResourceError, resolve_resource
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import load_scene
from physics_mapper.model.scene_loading import SceneLoading
from physics_mapper.ros.parameters import DEFAULT_DIAGNOSTICS_PERIOD
from physics_mapper.ros.qos import DIAGNOSTICS_QOS
from physics_mapper.ros.spinning import STOP_POLL, SignalStop

#: Seconds a scene may take to load before the node spins and reports what it is doing (a decomposition).
LOADING_REPORT_AFTER = 0.2


def resolve_scene_path(text: str) -> Path:
    """A scene file path, or a ``package://<pkg>/<path>`` URL (:mod:`physics_mapper.model.resources`).

    Without an ament index (pip wheels only), ``package://physics_mapper/`` is this installation's
    shipped files (:func:`~physics_mapper.model.shipped.share_directory`: the same ``config/`` tree).
    """
    if not text:
        raise InputError("parameter scene_file is required, e.g. --ros-args -p scene_file:=config/scenes/pyramid.yaml")
    try:
        return resolve_resource(text, None)
    except ResourceError as error:
        raise InputError(f"scene_file {error}") from None


def load_scene_spinning(node: Node, path: Path, stop: SignalStop) -> Scene:
    """The scene, loaded in a thread while ``node`` spins, reporting a decomposition in its diagnostics.

    A signal stops the load at once (the decomposition's child process is killed): KeyboardInterrupt.
    A node already spun by an executor (the managed node, configured from a service call) waits
    for the load without spinning itself.
    """
    loading = SceneLoading(path, load_scene)
    if loading.wait(LOADING_REPORT_AFTER):  # from the cache: nothing to report
        return loading.result()
    if node.executor is not None:
        while not loading.wait(STOP_POLL):
            if stop.requested:
                loading.cancel()
                raise KeyboardInterrupt
        return loading.result()
    publisher = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    reported, shown = -float("inf"), ""
    logger: Any = node.get_logger()  # type: ignore[no-untyped-call]  # rclpy 7 leaves it unannotated
    try:
        while not loading.done:
            if stop.requested:
                loading.cancel()
                raise KeyboardInterrupt
            # Reported at once when it changes (a decomposition that starts), else once a period; a
            # decomposition is also logged: it may end before a diagnostics subscriber is matched.
            activity = loading.activity or f"loading {path}"
            if activity != shown and loading.activity is not None:
                logger.info(clipped(printable(activity), MAX_DIAGNOSTIC_TEXT))
            if activity != shown or time.monotonic() - reported >= DEFAULT_DIAGNOSTICS_PERIOD:
                reported, shown = time.monotonic(), activity
                publisher.publish(loading_diagnostics(node, activity))
            executor.spin_once(timeout_sec=STOP_POLL / 2)
    finally:
        executor.remove_node(node)
        executor.shutdown()
        node.destroy_publisher(publisher)
    return loading.result()


def loading_diagnostics(node: Node, activity: str) -> DiagnosticArray:
    """A WARN search status while the scene loads: no search yet, and why."""
    status = DiagnosticStatus(
        level=DiagnosticStatus.WARN,
        name=f"{node.get_name()}: search",
        message=clipped(f"{activity}: the search starts when the geometry is ready", MAX_DIAGNOSTIC_TEXT),
        hardware_id=node.get_fully_qualified_name(),
    )
    message = DiagnosticArray(status=[status])
    message.header.stamp = node.get_clock().now().to_msg()
    return message
