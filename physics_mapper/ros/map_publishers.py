"""The configured node's outputs: the map, its markers, each object's poses, and ``/diagnostics``.

Every map message carries the newest input stamp the tick used (:mod:`physics_mapper.msg_adapters.results`
builds them); each object's pose topics are latched and published only when its poses or stamp change.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.publisher import Publisher
from visualization_msgs.msg import MarkerArray

from physics_mapper.mapping.mapper import TickReport
from physics_mapper.mapping.topics import (
    CONFIGURATION_TOPIC,
    MARKERS_TOPIC,
    SETTLED_TOPIC,
    object_pose_topic,
    object_settled_pose_topic,
)
from physics_mapper.model.scene import Scene
from physics_mapper.msg_adapters.results import configuration_msgs, markers_msg, object_pose_msgs
from physics_mapper.ros.node_diagnostics import NodeDiagnostics
from physics_mapper.search.results import SearchResult


@dataclass
class MapPublishers:
    """The output publishers of one configured node, and what they last published per object."""

    configuration: Publisher
    settled: Publisher
    markers: Publisher
    objects: list[tuple[Publisher, Publisher]]  # (chosen pose, settled pose) per scene object
    diagnostics: NodeDiagnostics
    published_objects: tuple[int, SearchResult] | None = field(default=None, init=False)

    def publish_map(self, report: TickReport, scene: Scene) -> None:
        """A tick's map; outputs carry the newest input stamp used."""
        result = report.result
        stamp_ns = report.snapshot.stamp_ns
        if result is None or stamp_ns is None:
            return
        configurations = configuration_msgs(result, frame_id=scene.frame_id, stamp_ns=stamp_ns)
        if configurations is None:
            return
        self.configuration.publish(configurations[0])
        self.settled.publish(configurations[1])
        self.markers.publish(markers_msg(result, scene, stamp_ns=stamp_ns))
        self._publish_objects(result, scene.frame_id, stamp_ns)

    def _publish_objects(self, result: SearchResult, frame_id: str, stamp_ns: int) -> None:
        """Each object's chosen and settled pose, when the map's poses or stamp changed (the topics are latched)."""
        last = self.published_objects
        if last is not None and (last[0], last[1].poses, last[1].settled_poses) == (
            stamp_ns,
            result.poses,
            result.settled_poses,
        ):
            return
        per_object = object_pose_msgs(result, frame_id=frame_id, stamp_ns=stamp_ns)
        if per_object is None:
            return
        for (pose_pub, settled_pub), (pose, settled) in zip(self.objects, per_object, strict=True):
            pose_pub.publish(pose)
            settled_pub.publish(settled)
        self.published_objects = (stamp_ns, result)


def map_publishers(
    publisher: Callable[[type, str], Publisher], object_names: Sequence[str], diagnostics: NodeDiagnostics
) -> MapPublishers:
    """The map's publishers, made by ``publisher`` (message type, topic): the map, its markers, each object's poses."""
    return MapPublishers(
        configuration=publisher(PoseArray, CONFIGURATION_TOPIC),
        settled=publisher(PoseArray, SETTLED_TOPIC),
        markers=publisher(MarkerArray, MARKERS_TOPIC),
        objects=[
            (publisher(PoseStamped, object_pose_topic(name)), publisher(PoseStamped, object_settled_pose_topic(name)))
            for name in object_names
        ],
        diagnostics=diagnostics,
    )
