"""The node's name, every topic name and the QoS of each, in one place (ROS-free, so the bags share them).

Inputs are relative to the node's namespace; outputs starting with ``~/`` are private to the
node. Bags record absolute names (as ``ros2 bag record`` does): :func:`recorded`, and the
``RECORDED_*`` and ``recorded_*`` names below, for a node in the root namespace.

QoS (:class:`TopicQos`; ``physics_mapper.ros.qos`` makes rclpy profiles of them, the bags record
them as rosbag2's offered QoS): inputs are best effort, volatile, depth 10 by default, which
matches both reliable publishers (``ros2 topic pub``, most pose estimators) and best-effort ones
(sensor-data QoS), or reliable with the node's ``input_reliability`` parameter; the map topics
are reliable and transient local, depth 1 (latched), so RViz or a recorder started later still
gets the last map; ``/diagnostics`` uses the default QoS (reliable, volatile, depth 10), like
diagnostic_updater.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

NODE_NAME = "physics_mapper"

InputReliability = Literal["best_effort", "reliable"]
INPUT_RELIABILITIES: tuple[InputReliability, ...] = ("best_effort", "reliable")


@dataclass(frozen=True)
class TopicQos:
    """A topic's QoS: reliable or best effort, transient local (latched) or volatile, keep-last ``depth``."""

    reliable: bool
    transient_local: bool
    depth: int


MAP_TOPIC_QOS = TopicQos(reliable=True, transient_local=True, depth=1)
DIAGNOSTICS_TOPIC_QOS = TopicQos(reliable=True, transient_local=False, depth=10)
#: tf2's listener and broadcaster QoS: /tf reliable and volatile, /tf_static latched, depth 100 both.
TF_TOPIC_QOS = TopicQos(reliable=True, transient_local=False, depth=100)
TF_STATIC_TOPIC_QOS = TopicQos(reliable=True, transient_local=True, depth=100)
_BEST_EFFORT_INPUT_QOS = TopicQos(reliable=False, transient_local=False, depth=10)


def input_topic_qos(reliability: InputReliability = "best_effort") -> TopicQos:
    """QoS of the hypothesis subscriptions for the node's ``input_reliability`` parameter."""
    return replace(_BEST_EFFORT_INPUT_QOS, reliable=reliability == "reliable")


# Outputs, relative to the node (``~``) or absolute.
CONFIGURATION_TOPIC = "~/configuration"
SETTLED_TOPIC = "~/settled_configuration"
MARKERS_TOPIC = "~/markers"
#: Latched beside the map: whether it is valid or a fallback, and the object names in the map's order.
MAP_STATUS_TOPIC = "~/map_status"
#: tf2's topics: transforms over time, and transforms that hold at every time (latched).
TF_TOPIC = "/tf"
TF_STATIC_TOPIC = "/tf_static"
#: The map as ``vision_msgs/Detection3DArray``: one Detection3D per object present, its id the object's name.
OBJECTS_TOPIC = "~/objects"
DIAGNOSTICS_TOPIC = "/diagnostics"
#: True poses of every object, in scene object order (written by ``generate``, read by ``replay``).
GROUND_TRUTH_TOPIC = "/ground_truth"


def poses_topic(object_name: str) -> str:
    """The object's PoseArray input topic, relative to the node's namespace."""
    return f"hypotheses/{object_name}"


def weights_topic(object_name: str) -> str:
    """The object's weights input topic, relative to the node's namespace."""
    return f"hypotheses/{object_name}/weights"


def object_pose_topic(object_name: str) -> str:
    """The object's chosen pose (``geometry_msgs/PoseStamped``), private to the node."""
    return f"~/objects/{object_name}/pose"


def object_settled_pose_topic(object_name: str) -> str:
    """The object's settled pose (``geometry_msgs/PoseStamped``), private to the node."""
    return f"~/objects/{object_name}/settled_pose"


def output_topic(topic: str, namespace: str = "/") -> str:
    """An output topic's full name for a node named :data:`NODE_NAME` in ``namespace``."""
    if not topic.startswith("~/"):
        return topic
    return f"{namespace.rstrip('/')}/{NODE_NAME}/{topic[2:]}"


def recorded(topic: str) -> str:
    """A topic's name as a bag records it for a node in the root namespace: ``hypotheses/a`` -> ``/hypotheses/a``."""
    return output_topic(topic) if topic.startswith("~/") else "/" + topic.lstrip("/")


def recorded_poses_topic(object_name: str) -> str:
    """An object's PoseArray input topic as a bag records it: ``/hypotheses/<object>``."""
    return recorded(poses_topic(object_name))


def recorded_weights_topic(object_name: str) -> str:
    """An object's weights input topic as a bag records it: ``/hypotheses/<object>/weights``."""
    return recorded(weights_topic(object_name))


RECORDED_CONFIGURATION_TOPIC = recorded(CONFIGURATION_TOPIC)
RECORDED_SETTLED_TOPIC = recorded(SETTLED_TOPIC)
RECORDED_MARKERS_TOPIC = recorded(MARKERS_TOPIC)
