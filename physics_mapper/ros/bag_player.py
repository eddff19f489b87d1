"""Play a bag into the live ROS 2 graph and record the node's outputs: ``ros2 bag play`` + ``record``.

The bag's messages are published as the raw CDR bytes stored in the bag (no conversion), at
their recorded times scaled by a rate, except on the topics recorded here: a bag recorded with
``ros2 bag record -a`` while a node ran holds that node's outputs, which would be recorded again
as this replay's. The node's outputs are recorded, also as raw bytes, into a new bag, stamped
with the receive time. The topic names are those of :mod:`physics_mapper.bags.evaluation`;
for a node in a namespace, the bag's topics and the node's outputs are taken inside that namespace
(``/diagnostics`` stays global) and recorded under their root-namespace names, so that recordings
compare.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription

from physics_mapper.bags.storage import DIAGNOSTIC_ARRAY, POSE_ARRAY, Bag, BagWriter
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.topics import (
    DIAGNOSTICS_TOPIC,
    RECORDED_CONFIGURATION_TOPIC,
    RECORDED_MARKERS_TOPIC,
    RECORDED_SETTLED_TOPIC,
)
from physics_mapper.ros.spinning import shutdown_ros

#: The node's outputs that are recorded, with their types; a bag's messages on these topics are not
#: played, nor an old run's markers.
RECORDED = (
    (RECORDED_CONFIGURATION_TOPIC, POSE_ARRAY),
    (RECORDED_SETTLED_TOPIC, POSE_ARRAY),
    (DIAGNOSTICS_TOPIC, DIAGNOSTIC_ARRAY),
)
#: For playing and recording alike. Reliable publishers match both reliable and best-effort
#: subscribers (the node's inputs are best effort); volatile subscribers do not receive a map
#: latched before the replay. QoSProfile.__init__ is unannotated in rclpy 7.
RELIABLE_VOLATILE_QOS = QoSProfile(  # type: ignore[no-untyped-call]
    depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE
)
#: Seconds between two progress lines.
PROGRESS_PERIOD = 1.0
#: Seconds of pause after the graph is connected, so that the first messages are not lost.
SETTLE_AFTER_DISCOVERY = 0.3


class ReplayError(RuntimeError):
    """The live replay cannot go on (no node listening, or it went away)."""


@dataclass(frozen=True)
class Playback:
    """rate: speed factor (2.0 plays twice as fast); wait: seconds to wait for the node's topics;
    tail: seconds to keep recording after the last message; namespace: the node's ROS namespace."""

    rate: float = 1.0
    wait: float = 15.0
    tail: float = 2.0
    namespace: str = "/"


def _in_namespace(topic: str) -> str:
    """A recorded topic name as seen by a node in a namespace: relative, except the global /diagnostics."""
    return topic if topic == DIAGNOSTICS_TOPIC else topic.lstrip("/")


def message_class(msgtype: str) -> Any:
    """The rclpy message class of ``pkg/msg/Type``, or None if that package is not installed."""
    package, _, name = msgtype.rpartition("/")
    try:
        return getattr(importlib.import_module(package.replace("/", ".")), name, None)
    except ImportError:
        return None


class _Recorder:
    """Raw subscriptions to the node's outputs, written to a bag as they arrive."""

    def __init__(self, node: Node, writer: BagWriter) -> None:
        self._node = node
        self._writer = writer
        self.counts = {topic: 0 for topic, _ in RECORDED}
        self.subscriptions: list[Subscription] = [
            node.create_subscription(
                message_class(msgtype),
                _in_namespace(topic),
                self._callback(topic, msgtype),
                RELIABLE_VOLATILE_QOS,
                raw=True,
            )
            for topic, msgtype in RECORDED
        ]

    def _callback(self, topic: str, msgtype: str) -> Callable[[bytes], None]:
        def record(raw: bytes) -> None:
            self._writer.write(topic, msgtype, self._node.get_clock().now().nanoseconds, raw)
            self.counts[topic] += 1

        return record


def _publishers(node: Node, bag: Bag, skipped: list[str]) -> dict[str, Publisher]:
    """A publisher per topic of the bag to play; ``skipped`` gets the others, each with the reason."""
    recorded_here = {topic for topic, _ in RECORDED}
    publishers: dict[str, Publisher] = {}
    for topic, msgtype in bag.topics.items():
        cls = message_class(msgtype)
        if topic in recorded_here:
            skipped.append(f"{topic} (recorded by this replay)")
        elif topic == RECORDED_MARKERS_TOPIC:
            skipped.append(f"{topic} (an old run's map: the node under test publishes its own)")
        elif cls is None:
            skipped.append(f"{topic} ({msgtype}: message package not installed)")
        else:
            publishers[topic] = node.create_publisher(cls, _in_namespace(topic), RELIABLE_VOLATILE_QOS)
    return publishers


def _wait_for_graph(
    executor: SingleThreadedExecutor,
    inputs: Sequence[Publisher],
    outputs: Sequence[Subscription],
    timeout: float,
    alive: Callable[[], bool],
) -> None:
    """Spin until every input topic has a subscriber and every output a publisher; ReplayError after ``timeout``."""
    end = time.monotonic() + timeout
    while True:
        unheard = [p.topic_name for p in inputs if p.get_subscription_count() == 0]
        silent = [s.topic_name for s in outputs if s.get_publisher_count() == 0]
        if not unheard and not silent:
            break
        if time.monotonic() >= end or not alive():
            raise ReplayError(
                f"no node is listening on {', '.join(unheard) or '-'} / publishing {', '.join(silent) or '-'} "
                f"after {timeout:g} s: start it first (physics-mapper node --ros-args -p scene_file:=SCENE) "
                "or pass --start-node"
            )
        executor.spin_once(timeout_sec=0.05)
    settle_until = time.monotonic() + SETTLE_AFTER_DISCOVERY
    while time.monotonic() < settle_until:
        executor.spin_once(timeout_sec=0.05)


def _spin_until(executor: SingleThreadedExecutor, instant: float) -> None:
    while (remaining := instant - time.monotonic()) > 0.0:
        executor.spin_once(timeout_sec=min(remaining, 0.05))


def play_and_record(
    bag: Bag,
    input_topics: Sequence[str],
    writer: BagWriter,
    playback: Playback,
    progress: Callable[[str], None],
    alive: Callable[[], bool] = lambda: True,
) -> dict[str, int]:
    """Publish ``bag`` with its timing scaled by ``playback.rate`` and record the node's outputs into ``writer``.

    ``input_topics`` must have a subscriber before playing starts. ``alive()`` false (a node we
    started has exited) stops the replay with ReplayError. Returns the messages recorded per topic.
    """
    rclpy.init(args=[])
    try:
        node = rclpy.create_node("physics_mapper_replay", namespace=playback.namespace)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        skipped: list[str] = []
        publishers = _publishers(node, bag, skipped)
        if skipped:
            progress(f"not played: {', '.join(skipped)}")
        recorder = _Recorder(node, writer)
        _wait_for_graph(executor, [publishers[t] for t in input_topics], recorder.subscriptions, playback.wait, alive)
        _play(executor, bag, publishers, playback, progress, recorder, alive)
        _spin_until(executor, time.monotonic() + playback.tail)
        executor.remove_node(node)
        node.destroy_node()  # type: ignore[no-untyped-call]
    finally:
        shutdown_ros()
    return recorder.counts


def _play(
    executor: SingleThreadedExecutor,
    bag: Bag,
    publishers: dict[str, Publisher],
    playback: Playback,
    progress: Callable[[str], None],
    recorder: _Recorder,
    alive: Callable[[], bool],
) -> None:
    if not bag.messages:
        return
    first = bag.messages[0].time_ns
    duration = (bag.messages[-1].time_ns - first) / NANOSECONDS_PER_SECOND / playback.rate
    start = next_report = time.monotonic()
    for index, message in enumerate(bag.messages):
        _spin_until(executor, start + (message.time_ns - first) / NANOSECONDS_PER_SECOND / playback.rate)
        if not alive():
            raise ReplayError("the node exited during the replay")
        publisher = publishers.get(message.topic)
        if publisher is not None:
            publisher.publish(message.raw)
        if time.monotonic() >= next_report or index == len(bag.messages) - 1:
            next_report += PROGRESS_PERIOD
            progress(
                f"{time.monotonic() - start:5.1f}/{duration:.1f} s: {index + 1}/{len(bag.messages)} messages played, "
                f"{recorder.counts[RECORDED_CONFIGURATION_TOPIC]} configurations received"
            )
