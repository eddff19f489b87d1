"""Shared helpers for tests over real DDS: the node as a subprocess, and an in-test rclpy client.

The node under test runs in its own process (``physics_mapper.ros.child_process``); the test talks to
it through :class:`RosClient`, an rclpy node with its own context, on the ROS domain that
conftest.py chose for this pytest run.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import Marker, MarkerArray

from physics_mapper.mapping.topics import (
    CONFIGURATION_TOPIC,
    DIAGNOSTICS_TOPIC,
    MARKERS_TOPIC,
    NODE_NAME,
    SETTLED_TOPIC,
    output_topic,
    poses_topic,
    weights_topic,
)
from physics_mapper.model.errors import EXIT_BAD_INPUT
from physics_mapper.msg_adapters.hypotheses import nanoseconds_from_stamp
from physics_mapper.ros.child_process import start_node, stop_node
from physics_mapper.ros.qos import DIAGNOSTICS_QOS, MAP_QOS

#: The search status keys every diagnostics message carries.
REQUIRED_DIAGNOSTIC_KEYS = (
    "nodes visited",
    "nodes expanded",
    "nodes bounded",
    "rejected by collision",
    "rejected by stability",
    "best code",
    "p(C)",
    "J",
    "search time [s]",
    "deadline [s]",
    "configurations per second",
)
#: The installed console script, as users run it.
PHYSICS_MAPPER = Path(sys.executable).parent / "physics-mapper"
#: Generous liveness bounds (seconds): a shared 2-core machine may be slow, never this slow.
STARTUP_TIMEOUT = 30.0
REPLY_TIMEOUT = 15.0
#: Seconds after which a request without an answer is sent again: a service's first answer is lost when
#: it comes before the client's response reader is matched (service_is_ready sees the request side only).
RESEND_AFTER = 2.0


class NodeProcess:
    """The node running as a child process; its output is kept in a file for assertions."""

    def __init__(
        self,
        scene_file: str | Path,
        parameters: Mapping[str, object],
        log_path: Path,
        namespace: str,
        *,
        managed: bool = False,
        remaps: Mapping[str, str] | None = None,
    ) -> None:
        self.log_path = log_path
        self._log: IO[str] = log_path.open("w")
        self.process = start_node(
            scene_file, parameters, namespace=namespace, output=self._log, managed=managed, remaps=remaps
        )

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def stop(self) -> int:
        code = stop_node(self.process)
        self._log.close()
        return code

    def output(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text()


def search_status(msg: DiagnosticArray) -> DiagnosticStatus | None:
    """The node's search status in a DiagnosticArray, if it is one of the node's."""
    return next((s for s in msg.status if s.name == f"{NODE_NAME}: search"), None)


def node_full_name(namespace: str) -> str:
    return f"{namespace.rstrip('/')}/{NODE_NAME}"


def object_status(msg: DiagnosticArray, name: str) -> DiagnosticStatus:
    return next(s for s in msg.status if s.name == f"{NODE_NAME}: hypotheses/{name}")


def values(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def stamp_ns_of(msg: PoseArray | Marker) -> int:
    """A message's header stamp, integer nanoseconds (exact)."""
    return nanoseconds_from_stamp(msg.header.stamp)


class RosClient:
    """Publishes into the node running in ``namespace`` and records what it publishes."""

    def __init__(self, namespace: str) -> None:
        self.namespace = namespace
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("physics_mapper_test", namespace=namespace, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.configurations: list[PoseArray] = []
        self.settled: list[PoseArray] = []
        self.markers: list[MarkerArray] = []
        self.diagnostics: list[DiagnosticArray] = []
        for topic, msg_type, messages in (
            (CONFIGURATION_TOPIC, PoseArray, self.configurations),
            (SETTLED_TOPIC, PoseArray, self.settled),
            (MARKERS_TOPIC, MarkerArray, self.markers),
        ):
            self.node.create_subscription(msg_type, output_topic(topic, namespace), messages.append, MAP_QOS)
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics, DIAGNOSTICS_QOS)
        self._publishers: dict[str, Any] = {}
        self.parameters = AsyncParameterClient(self.node, node_full_name(namespace))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        """Keep the node's own diagnostics: other nodes publish on /diagnostics too."""
        search = search_status(msg)
        if search is not None and search.hardware_id == node_full_name(self.namespace):
            self.diagnostics.append(msg)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()  # type: ignore[no-untyped-call]  # rclpy 7 leaves it unannotated
        rclpy.try_shutdown(context=self.context)  # type: ignore[attr-defined]  # exported, not re-declared

    def _publisher(self, msg_type: type, topic: str) -> Any:
        if topic not in self._publishers:
            self._publishers[topic] = self.node.create_publisher(msg_type, topic, 10)
        return self._publishers[topic]

    def publish(self, object_name: str, poses: PoseArray, weights: Float64MultiArray | None = None) -> None:
        """Publish an object's PoseArray, then its weights (if given)."""
        poses_pub = self._publisher(PoseArray, poses_topic(object_name))
        weights_pub = self._publisher(Float64MultiArray, weights_topic(object_name))
        self.wait_for(lambda: poses_pub.get_subscription_count() > 0 and weights_pub.get_subscription_count() > 0)
        poses_pub.publish(poses)
        if weights is not None:
            weights_pub.publish(weights)

    def keep_publishing(
        self, publish: Callable[[], None], until: Callable[[], bool], what: str, timeout: float = REPLY_TIMEOUT
    ) -> None:
        """Publish every half second until ``until()`` holds: a message sent while the node's
        reader has not yet matched a new writer is lost (DDS discovery is not symmetric)."""
        end = time.monotonic() + timeout
        while not until():
            assert time.monotonic() < end, f"timed out after {timeout:g} s waiting for {what}"
            publish()
            self.spin_until(until, timeout=0.5)

    def map_of(self, stamp_ns: int, objects: int) -> PoseArray | None:
        """The first configuration stamped ``stamp_ns`` that holds ``objects`` poses (a map made before
        every object's hypotheses came leaves the others out), or None."""
        return next((c for c in self.configurations if stamp_ns_of(c) == stamp_ns and len(c.poses) == objects), None)

    def spin_until(self, predicate: Callable[[], bool], timeout: float = REPLY_TIMEOUT) -> bool:
        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() >= end:
                return False
            self.executor.spin_once(timeout_sec=0.05)
        return True

    def wait_for(self, predicate: Callable[[], bool], timeout: float = REPLY_TIMEOUT, what: str = "") -> None:
        assert self.spin_until(predicate, timeout), f"timed out after {timeout:g} s waiting for {what or predicate}"

    def next_diagnostics(
        self, predicate: Callable[[DiagnosticArray], bool], timeout: float = REPLY_TIMEOUT, what: str = ""
    ) -> DiagnosticArray:
        """The first DiagnosticArray arriving from now on that satisfies ``predicate``."""
        start = len(self.diagnostics)

        def found() -> DiagnosticArray | None:
            return next((d for d in self.diagnostics[start:] if predicate(d)), None)

        self.wait_for(lambda: found() is not None, timeout, what or "diagnostics")
        result = found()
        assert result is not None
        return result

    def answered(self, call: Callable[[], Any], what: str) -> Any:
        """The result of the request ``call()`` sends (its future), sent again every :data:`RESEND_AFTER`
        seconds until answered: for requests that may be repeated (reads, sets of the same values)."""
        end = time.monotonic() + REPLY_TIMEOUT
        while True:
            future = call()
            if self.spin_until(future.done, RESEND_AFTER):
                return future.result()
            assert time.monotonic() < end, f"timed out after {REPLY_TIMEOUT:g} s waiting for {what}"

    def set_parameter(self, name: str, value: object) -> tuple[bool, str]:
        """Set one of the node's parameters through its SetParameters service: (successful, reason)."""
        return self.set_parameters({name: value})[0]

    def set_parameters(self, values: Mapping[str, object]) -> list[tuple[bool, str]]:
        """Set several parameters in one SetParameters request, in the mapping's order: each (successful, reason)."""
        self.wait_for(lambda: self.parameters.wait_for_services(timeout_sec=0.1), what="parameter services")
        request = [Parameter(name, value=value) for name, value in values.items()]  # type: ignore[no-untyped-call]
        answer = self.answered(lambda: self.parameters.set_parameters(request), f"set_parameters {', '.join(values)}")
        results = answer.results
        return [(bool(result.successful), str(result.reason)) for result in results]

    def set_parameters_atomically(self, values: Mapping[str, object]) -> tuple[bool, str]:
        """Set several parameters through the SetParametersAtomically service: (successful, reason)."""
        self.wait_for(lambda: self.parameters.wait_for_services(timeout_sec=0.1), what="parameter services")
        request = [Parameter(name, value=value) for name, value in values.items()]  # type: ignore[no-untyped-call]
        answer = self.answered(
            lambda: self.parameters.set_parameters_atomically(request), f"set_parameters_atomically {', '.join(values)}"
        )
        result = answer.result
        return bool(result.successful), str(result.reason)

    def get_parameters(self, *names: str) -> list[object]:
        """The node's current values of ``names``."""
        self.wait_for(lambda: self.parameters.wait_for_services(timeout_sec=0.1), what="parameter services")
        answer = self.answered(
            lambda: self.parameters.get_parameters(list(names)), f"get_parameters {', '.join(names)}"
        )
        return [parameter_value_to_python(v) for v in answer.values]

    def latched(self, msg_type: type, topic: str) -> list[Any]:
        """Subscribe anew (a late joiner) to one of the node's latched outputs; its messages arrive in the list."""
        messages: list[Any] = []
        self.node.create_subscription(msg_type, output_topic(topic, self.namespace), messages.append, MAP_QOS)
        return messages


def run_cli(*args: str, cwd: Path | None = None, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    """Run ``physics-mapper ARGS`` in a child process (same interpreter and environment)."""
    command = [str(PHYSICS_MAPPER), *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout, cwd=cwd, check=False)


def one_error_line(completed: subprocess.CompletedProcess[str], *fragments: str) -> str:
    """The single stderr line of a refused command (exit 2), holding every fragment."""
    assert completed.returncode == EXIT_BAD_INPUT, completed.stderr
    lines = completed.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in completed.stderr, completed.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


def last_error_line(completed: subprocess.CompletedProcess[str], *fragments: str) -> str:
    """The error line ending a refused command's stderr (exit 2, no traceback), after its progress lines."""
    assert completed.returncode == EXIT_BAD_INPUT and "Traceback" not in completed.stderr, completed.stderr
    line = completed.stderr.splitlines()[-1]
    assert ": error: " in line and all(fragment in line for fragment in fragments), line
    return line


class Lifecycle:
    """A client of one lifecycle node's get_state and change_state services."""

    def __init__(self, client: RosClient, namespace: str) -> None:
        self.client = client
        node = node_full_name(namespace)
        self._get = client.node.create_client(GetState, f"{node}/get_state")
        self._change = client.node.create_client(ChangeState, f"{node}/change_state")
        client.wait_for(
            lambda: self._get.service_is_ready() and self._change.service_is_ready(),
            STARTUP_TIMEOUT,
            "the lifecycle services",
        )
        self.state()  # answered once: the services' answers reach this client (RosClient.answered)

    def state(self) -> int:
        return int(self.client.answered(lambda: self._get.call_async(GetState.Request()), "get_state").current_state.id)

    def change(self, transition: int) -> bool:
        future = self._change.call_async(ChangeState.Request(transition=Transition(id=transition)))
        self.client.wait_for(future.done, REPLY_TIMEOUT, f"change_state {transition}")
        return bool(future.result().success)  # type: ignore[no-untyped-call]
