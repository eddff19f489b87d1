"""The configured node's outputs: the map, its status, its markers, each object's poses and /tf frame,
``~/objects``, and ``/diagnostics``.


Every map message carries the newest input stamp the tick used (:mod:`physics_mapper.msg_adapters.results`
builds them); each object's pose topics are latched and published only when its poses or stamp change.
``~/map_status`` (latched) goes out with every map, before it, with the same stamp: valid or a
fallback, and the object names in the map's order; before the first map it says ``no map yet``.
With ``publish_tf``, each object's pose (``tf_pose``: settled or chosen) goes on ``/tf`` as frame
``<tf_prefix><object>`` of the scene's frame, with every map (``/tf`` is not latched: a listener
started later gets the next tick's); ``~/objects`` carries the same pose.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.node import Node
from rclpy.publisher import Publisher
from visualization_msgs.msg import MarkerArray

from physics_mapper.mapping.mapper import TickReport
from physics_mapper.mapping.topics import (
    CONFIGURATION_TOPIC,
    MAP_STATUS_TOPIC,
    MARKERS_TOPIC,
    OBJECTS_TOPIC,
    SETTLED_TOPIC,
    TF_TOPIC,
    object_pose_topic,
    object_settled_pose_topic,
)
from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Scene
from physics_mapper.msg_adapters.results import configuration_msgs, map_status_msg, markers_msg, object_pose_msgs
from physics_mapper.msg_adapters.transforms import object_transforms
from physics_mapper.ros.node_diagnostics import NodeDiagnostics
from physics_mapper.ros.qos import TF_QOS
from physics_mapper.search.results import SearchResult


@dataclass(frozen=True)
class TfOutput:
    """The ``publish_tf``, ``tf_prefix`` and ``tf_pose`` parameters: whether, as what and which pose (the
    pose ``~/objects`` carries too)."""

    enabled: bool
    prefix: str
    settled: bool

    def poses(self, result: SearchResult) -> tuple[Pose, ...] | None:
        """The map's poses ``tf_pose`` selects: the settled ones or the chosen hypotheses (None: none)."""
        return result.settled_poses if self.settled else result.poses

    @staticmethod
    def of(values: Mapping[str, Any]) -> TfOutput:
        """From the node's parameter values."""
        return TfOutput(bool(values["publish_tf"]), str(values["tf_prefix"]), values["tf_pose"] == "settled")


@dataclass
class MapPublishers:
    """The output publishers of one configured node, and what they last published per object.

    ``tf``: the ``/tf`` publisher and ``TFMessage`` type where tf2_msgs is installed, else None.
    """

    configuration: Publisher
    settled: Publisher
    markers: Publisher
    status: Publisher
    objects: list[tuple[Publisher, Publisher]]  # (chosen pose, settled pose) per scene object
    diagnostics: NodeDiagnostics
    status_name: str  # the map status's name, ``<node>: map``
    hardware_id: str  # the node's fully qualified name, as in /diagnostics
    tf: tuple[Publisher, Any] | None = None
    #: ``~/objects`` (the map as ``vision_msgs/Detection3DArray``), where vision_msgs is installed.
    detections: Publisher | None = None
    published_objects: tuple[int, SearchResult, tuple[int, ...]] | None = field(default=None, init=False)

    def publish_status(
        self, result: SearchResult | None, scene: Scene, stamp_ns: int, present: tuple[int, ...] | None = None
    ) -> None:
        """``~/map_status`` for the map ``result`` of the objects ``present``, stamped ``stamp_ns`` (None: no map)."""
        message = map_status_msg(
            result, scene, name=self.status_name, hardware_id=self.hardware_id, stamp_ns=stamp_ns, present=present
        )
        self.status.publish(message)

    def publish_map(self, report: TickReport, scene: Scene, tf: TfOutput) -> None:
        """A tick's map of the objects present; outputs carry the newest input stamp used."""
        result = report.result
        stamp_ns = report.snapshot.stamp_ns
        if result is None or stamp_ns is None:
            return
        present = report.present
        configurations = configuration_msgs(result, frame_id=scene.frame_id, stamp_ns=stamp_ns, present=present)
        if configurations is None:
            return
        self.publish_status(result, scene, stamp_ns, present)
        self._publish_tf(result, scene, stamp_ns, tf, present)
        self.configuration.publish(configurations[0])
        self.settled.publish(configurations[1])
        self.markers.publish(markers_msg(result, scene, stamp_ns=stamp_ns, present=present))
        self._publish_objects(result, scene.frame_id, stamp_ns, present)
        if self.detections is not None:
            from physics_mapper.msg_adapters.objects import objects_msg  # needs vision_msgs: imported where it is

            self.detections.publish(objects_msg(report, scene, tf.poses(result), stamp_ns=stamp_ns))

    def _publish_tf(
        self, result: SearchResult, scene: Scene, stamp_ns: int, tf: TfOutput, present: tuple[int, ...]
    ) -> None:
        """Each present object's frame on /tf, when ``publish_tf`` is on (and tf2_msgs installed)."""
        poses = tf.poses(result)
        if not tf.enabled or self.tf is None or poses is None:
            return
        publisher, message_type = self.tf
        names = scene.object_names
        transforms = object_transforms(
            [poses[i] for i in present],
            [names[i] for i in present],
            frame_id=scene.frame_id,
            prefix=tf.prefix,
            stamp_ns=stamp_ns,
        )
        publisher.publish(message_type(transforms=transforms))

    def _publish_objects(self, result: SearchResult, frame_id: str, stamp_ns: int, present: tuple[int, ...]) -> None:
        """Each present object's chosen and settled pose, when the map's poses, stamp or objects changed (the
        topics are latched: an object the map leaves out keeps its last pose there)."""
        last = self.published_objects
        if last is not None and (last[0], last[1].poses, last[1].settled_poses, last[2]) == (
            stamp_ns,
            result.poses,
            result.settled_poses,
            present,
        ):
            return
        per_object = object_pose_msgs(result, frame_id=frame_id, stamp_ns=stamp_ns, present=present)
        if per_object is None:
            return
        for (pose_pub, settled_pub), poses in zip(self.objects, per_object, strict=True):
            if poses is not None:
                pose_pub.publish(poses[0])
                settled_pub.publish(poses[1])
        self.published_objects = (stamp_ns, result, present)


def map_publishers(
    publisher: Callable[..., Publisher],
    object_names: Sequence[str],
    diagnostics: NodeDiagnostics,
    node: Node,
) -> MapPublishers:
    """The map's publishers, made by ``publisher`` (message type, topic[, QoS]): the map, its status, its
    markers, each object's poses, /tf where tf2_msgs is installed and ``~/objects`` where vision_msgs is;
    ``node``'s names name the map status."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        tf = None
    else:
        tf = (publisher(TFMessage, TF_TOPIC, TF_QOS), TFMessage)
    try:
        from vision_msgs.msg import Detection3DArray
    except ImportError:
        detections = None
    else:
        detections = publisher(Detection3DArray, OBJECTS_TOPIC)
    return MapPublishers(
        configuration=publisher(PoseArray, CONFIGURATION_TOPIC),
        settled=publisher(PoseArray, SETTLED_TOPIC),
        markers=publisher(MarkerArray, MARKERS_TOPIC),
        status=publisher(DiagnosticArray, MAP_STATUS_TOPIC),
        objects=[
            (publisher(PoseStamped, object_pose_topic(name)), publisher(PoseStamped, object_settled_pose_topic(name)))
            for name in object_names
        ],
        diagnostics=diagnostics,
        status_name=f"{node.get_name()}: map",
        hardware_id=node.get_fully_qualified_name(),
        tf=tf,
        detections=detections,
    )
