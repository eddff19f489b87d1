"""Play a bag into the live ROS 2 graph and record the node's outputs: ``ros2 bag play`` + ``record``.

- **Streamed.** Messages are read from the bag as they are played, a bounded window ahead
  (:class:`~physics_mapper.bags.read_ahead.ReadAhead`), so a bag of any size plays in bounded memory.
- **Only what the node consumes**, by default: the scene's ``/hypotheses/<object>`` and their
  weights; ``topics`` adds others, ``all_topics`` plays every topic but ``/rosout``,
  ``/parameter_events`` and ``/clock`` (those only when named). Never the topics recorded here, nor
  an old run's markers: a bag recorded with ``ros2 bag record -a`` while a node ran holds that
  node's outputs, which would be recorded again as this replay's.
- **Recorded QoS honoured**: each topic is published with the reliability and durability its
  publishers offered when it was recorded (:func:`~physics_mapper.ros.qos.playback_qos`); the
  node's outputs are recorded with the profiles their publishers offer (rosbag2's
  ``offered_qos_profiles``), so that ``ros2 bag play`` of the recording latches the map again.
- **Raw bytes**: messages are published as the CDR bytes stored in the bag, and recorded as
  received, stamped with the receive time, scaled in time by a rate.
- **Exhaustive** (lockstep): after each snapshot of hypotheses (:mod:`physics_mapper.evaluation.snapshots`)
  the replay waits until the node's diagnostics report a finished search on exactly that
  snapshot's PoseArrays (their stamps), so live results do not depend on the machine's speed.

Topic names are those of :mod:`physics_mapper.evaluation.snapshot_results`; for a node in a namespace, the
bag's topics and the node's outputs are taken inside that namespace (``/diagnostics`` stays
global) and recorded under their root-namespace names, so that recordings compare.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable, Collection, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription

from physics_mapper.bags.read_ahead import ReadAhead
from physics_mapper.bags.storage import DIAGNOSTIC_ARRAY, POSE_ARRAY, BagInfo, BagMessage, BagWriter, stream_messages
from physics_mapper.evaluation.snapshots import BagSnapshot
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.topics import (
    DIAGNOSTICS_TOPIC,
    NODE_NAME,
    RECORDED_CONFIGURATION_TOPIC,
    RECORDED_MARKERS_TOPIC,
    RECORDED_SETTLED_TOPIC,
    TopicQos,
)
from physics_mapper.ros.qos import PLAYBACK_DEPTH, playback_qos, qos_profile, recorded_qos
from physics_mapper.ros.spinning import ros_for_command, spin_once

#: The node's outputs that are recorded, with their types; a bag's messages on these topics are not
#: played, nor an old run's markers.
RECORDED = (
    (RECORDED_CONFIGURATION_TOPIC, POSE_ARRAY),
    (RECORDED_SETTLED_TOPIC, POSE_ARRAY),
    (DIAGNOSTICS_TOPIC, DIAGNOSTIC_ARRAY),
)
#: Topics of a ``ros2 bag record -a`` bag that a replay plays only when named: the graph's own.
NEVER_BY_DEFAULT = ("/rosout", "/parameter_events", "/clock")
#: The recorder's subscriptions: reliable, so that they match every publisher, and volatile, so that
#: they do not receive a map latched before the replay.
RECORDER_QOS = qos_profile(TopicQos(reliable=True, transient_local=False, depth=PLAYBACK_DEPTH))
#: Seconds between two progress lines.
PROGRESS_PERIOD = 1.0
#: Seconds of pause after the graph is connected, so that the first messages are not lost.
SETTLE_AFTER_DISCOVERY = 0.3


class ReplayError(RuntimeError):
    """The live replay cannot go on (no node listening, or it went away, or an exhaustive search did not come)."""


@dataclass(frozen=True)
class Playback:
    """How to play a bag.

    rate: speed factor (2.0 plays twice as fast); wait: seconds to wait for the node's topics, and
    in ``exhaustive`` replays for each search; tail: seconds to keep recording after the last
    message; namespace: the node's ROS namespace; topics: topics played besides those the node
    consumes; all_topics: play every topic (but :data:`NEVER_BY_DEFAULT` unless in ``topics``);
    exhaustive: after each snapshot, wait for the node's finished search on it; node_name: the
    node's name (a launch file's ``name=``, ``-r __node:=...``), whose outputs are recorded.
    """

    rate: float = 1.0
    wait: float = 15.0
    tail: float = 2.0
    namespace: str = "/"
    topics: tuple[str, ...] = ()
    all_topics: bool = False
    exhaustive: bool = False
    node_name: str = NODE_NAME


def _in_namespace(topic: str, node_name: str = NODE_NAME) -> str:
    """A recorded topic name as seen by a node in a namespace: relative, except the global /diagnostics;
    the node's own outputs (``/physics_mapper/...`` in a bag) under its actual ``node_name``."""
    if topic == DIAGNOSTICS_TOPIC:
        return topic
    relative = topic.lstrip("/")
    own = f"{NODE_NAME}/"
    return node_name + "/" + relative.removeprefix(own) if relative.startswith(own) else relative


def message_class(msgtype: str) -> Any:
    """The rclpy message class of ``pkg/msg/Type``, or None if that package is not installed."""
    package, _, name = msgtype.rpartition("/")
    try:
        return getattr(importlib.import_module(package.replace("/", ".")), name, None)
    except ImportError:
        return None


def played_topics(info: BagInfo, consumed: Collection[str], playback: Playback) -> tuple[list[str], list[str]]:
    """The topics of the bag to play, and the others, each with the reason it is not played."""
    recorded_here = {topic for topic, _ in RECORDED}
    played, skipped = [], []
    for topic, msgtype in info.topics.items():
        named = topic in playback.topics
        if topic in recorded_here:
            skipped.append(f"{topic} (recorded by this replay)")
        elif topic == RECORDED_MARKERS_TOPIC:
            skipped.append(f"{topic} (an old run's map: the node under test publishes its own)")
        elif message_class(msgtype) is None:
            skipped.append(f"{topic} ({msgtype}: message package not installed)")
        elif topic in consumed or named or (playback.all_topics and topic not in NEVER_BY_DEFAULT):
            played.append(topic)
        elif topic in NEVER_BY_DEFAULT:
            skipped.append(f"{topic} (the graph's own; --topics {topic} plays it)")
        else:
            skipped.append(f"{topic} (not consumed by the node; --topics or --all-topics plays it)")
    return played, skipped


class _Recorder:
    """Raw subscriptions to the node's outputs, written to a bag as they arrive (diagnostics also to a listener).

    Recording starts with :meth:`add_topics`, once the node's publishers are known.
    """

    def __init__(self, node: Node, writer: BagWriter, on_diagnostics: Callable[[bytes], None], node_name: str) -> None:
        self._node = node
        self._writer = writer
        self._on_diagnostics = on_diagnostics
        self._recording = False
        self.counts = {topic: 0 for topic, _ in RECORDED}
        self.subscriptions: list[Subscription] = [
            node.create_subscription(
                message_class(msgtype),
                _in_namespace(topic, node_name),
                self._callback(topic, msgtype),
                RECORDER_QOS,
                raw=True,
            )
            for topic, msgtype in RECORDED
        ]

    def add_topics(self) -> None:
        """Add the recorded topics to the bag with the QoS their publishers offer (call once they are found)."""
        for (topic, msgtype), subscription in zip(RECORDED, self.subscriptions, strict=True):
            publishers = self._node.get_publishers_info_by_topic(subscription.topic_name)
            self._writer.add_topic(topic, msgtype, [recorded_qos(p.qos_profile) for p in publishers])
        self._recording = True

    def _callback(self, topic: str, msgtype: str) -> Callable[[bytes], None]:
        def record(raw: bytes) -> None:
            if not self._recording:
                return
            self._writer.write(topic, msgtype, self._node.get_clock().now().nanoseconds, raw)
            self.counts[topic] += 1
            if topic == DIAGNOSTICS_TOPIC:
                self._on_diagnostics(raw)

        return record


class _Searches:
    """The node's searches as its diagnostics report them: finished or not, on which PoseArrays (stamps)."""

    def __init__(self, namespace: str, node_name: str, object_names: Sequence[str]) -> None:
        self._hardware_id = f"{namespace.rstrip('/')}/{node_name}"
        self._node_name = node_name
        self._object_names = object_names
        self.latest: tuple[bool, tuple[int, ...]] | None = None
        self.latest_message = "no diagnostics from the node yet"

    def on_diagnostics(self, raw: bytes) -> None:
        array = deserialize_message(raw, DiagnosticArray)
        statuses = {s.name: s for s in array.status if s.hardware_id == self._hardware_id}
        search = statuses.get(f"{self._node_name}: search")
        if search is None:
            return
        stamps = []
        for name in self._object_names:
            status = statuses.get(f"{self._node_name}: hypotheses/{name}")
            values = {kv.key: kv.value for kv in status.values} if status is not None else {}
            stamps.append(int(values.get("stamp [ns]", "-1")))
        finished = {kv.key: kv.value for kv in search.values}.get("finished") == "true"
        self.latest = (finished, tuple(stamps))
        self.latest_message = search.message


def _publishers(node: Node, info: BagInfo, topics: Iterable[str]) -> dict[str, Publisher]:
    """A publisher per played topic, with the QoS its recorded publishers offered."""
    return {
        topic: node.create_publisher(
            message_class(info.topics[topic]), _in_namespace(topic), playback_qos(info.offered_qos.get(topic, ()))
        )
        for topic in topics
    }


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
            missing = ([f"no node listens on {', '.join(unheard)}"] if unheard else []) + (
                [f"no node publishes {', '.join(silent)}"] if silent else []
            )
            raise ReplayError(
                f"{'; '.join(missing)} after {timeout:g} s: start it first (physics-mapper node --ros-args -p "
                "scene_file:=SCENE), pass --start-node, or name it with --namespace and --node-name"
            )
        spin_once(executor, 0.05)
    _spin_until(executor, time.monotonic() + SETTLE_AFTER_DISCOVERY)


def _spin_until(executor: SingleThreadedExecutor, instant: float) -> None:
    while (remaining := instant - time.monotonic()) > 0.0:
        spin_once(executor, min(remaining, 0.05))


def play_and_record(
    info: BagInfo,
    consumed: Sequence[str],
    writer: BagWriter,
    playback: Playback,
    progress: Callable[[str], None],
    alive: Callable[[], bool] = lambda: True,
    snapshots: Sequence[BagSnapshot] = (),
    object_names: Sequence[str] = (),
) -> dict[str, int]:
    """Publish the bag ``info`` describes, its timing scaled by ``playback.rate``; record the node's outputs.

    ``consumed`` are the node's input topics (absolute): played, and each must have a subscriber
    before playing starts. ``alive()`` false (a node we started has exited) stops the replay with
    ReplayError. With ``playback.exhaustive``, the replay waits after each of ``snapshots`` for the
    node's finished search on it (``object_names``: the scene's objects, in order). Returns the
    messages recorded per topic.
    """
    with ros_for_command():
        node = rclpy.create_node("physics_mapper_replay", namespace=playback.namespace)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        played, skipped = played_topics(info, consumed, playback)
        if skipped:
            progress(f"not played: {', '.join(skipped)}")
        publishers = _publishers(node, info, played)
        searches = _Searches(playback.namespace, playback.node_name, object_names)
        recorder = _Recorder(node, writer, searches.on_diagnostics, playback.node_name)
        inputs = [publishers[t] for t in consumed if t in publishers]
        _wait_for_graph(executor, inputs, recorder.subscriptions, playback.wait, alive)
        recorder.add_topics()
        waits = list(snapshots) if playback.exhaustive else []
        with ReadAhead(stream_messages(info.path, played, verify=False)) as messages:
            total = sum(info.counts[t] for t in played)
            player = _Player(executor, publishers, playback, progress, recorder, alive, searches)
            player.play(messages, total, waits)
        _spin_until(executor, time.monotonic() + playback.tail)
        executor.remove_node(node)
        node.destroy_node()  # type: ignore[no-untyped-call]
    return recorder.counts


@dataclass
class _Player:
    executor: SingleThreadedExecutor
    publishers: dict[str, Publisher]
    playback: Playback
    progress: Callable[[str], None]
    recorder: _Recorder
    alive: Callable[[], bool]
    searches: _Searches

    def play(self, messages: Iterable[BagMessage], total: int, waits: list[BagSnapshot]) -> None:
        """Publish ``messages`` at their recorded times; after each of ``waits`` (time order) wait for its search."""
        first: int | None = None
        start = next_report = time.monotonic()
        index = 0
        for index, message in enumerate(messages, 1):
            if first is None:
                first = message.time_ns
            start += self._wait_before(message.time_ns, waits)
            _spin_until(self.executor, start + (message.time_ns - first) / NANOSECONDS_PER_SECOND / self.playback.rate)
            if not self.alive():
                raise ReplayError("the node exited during the replay")
            self.publishers[message.topic].publish(message.raw)
            if time.monotonic() >= next_report:
                next_report = time.monotonic() + PROGRESS_PERIOD
                self._report(index, total, start)
        start += self._wait_before(None, waits)
        self._report(index, total, start)

    def _wait_before(self, time_ns: int | None, waits: list[BagSnapshot]) -> float:
        """Wait for the search on every snapshot that ends before ``time_ns`` (None: all); the seconds waited."""
        began = time.monotonic()
        while waits and (time_ns is None or waits[0].time_ns < time_ns):
            snapshot = waits.pop(0)
            self._wait_for_search(snapshot)
        return time.monotonic() - began

    def _wait_for_search(self, snapshot: BagSnapshot) -> None:
        """Spin until the node reports a finished search on exactly ``snapshot``'s PoseArrays."""
        self.searches.latest = None  # only diagnostics that arrive from now on count
        end = time.monotonic() + self.playback.wait
        while self.searches.latest != (True, snapshot.stamps_ns):
            if time.monotonic() >= end or not self.alive():
                raise ReplayError(
                    f"the node reported no finished search on the hypotheses stamped {snapshot.stamp_ns} ns "
                    f"within {self.playback.wait:g} s (its last diagnostics: {self.searches.latest_message})"
                )
            spin_once(self.executor, 0.05)

    def _report(self, played: int, total: int, start: float) -> None:
        configurations = self.recorder.counts[RECORDED_CONFIGURATION_TOPIC]
        elapsed = time.monotonic() - start
        self.progress(f"{elapsed:5.1f} s: {played}/{total} messages played, {configurations} configurations received")
