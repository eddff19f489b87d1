"""The node's name and every topic name, in one place (ROS-free, so the bags share them).

Inputs are relative to the node's namespace; outputs starting with ``~/`` are private to the
node. Bags record absolute names (as ``ros2 bag record`` does): :func:`recorded`, and the
``RECORDED_*`` and ``recorded_*`` names below, for a node in the root namespace.
"""

from __future__ import annotations

NODE_NAME = "physics_mapper"

# Outputs, relative to the node (``~``) or absolute.
CONFIGURATION_TOPIC = "~/configuration"
SETTLED_TOPIC = "~/settled_configuration"
MARKERS_TOPIC = "~/markers"
DIAGNOSTICS_TOPIC = "/diagnostics"
#: True poses of every object, in scene object order (written by ``generate``, read by ``replay``).
GROUND_TRUTH_TOPIC = "/ground_truth"


def poses_topic(object_name: str) -> str:
    """The object's PoseArray input topic, relative to the node's namespace."""
    return f"hypotheses/{object_name}"


def weights_topic(object_name: str) -> str:
    """The object's weights input topic, relative to the node's namespace."""
    return f"hypotheses/{object_name}/weights"


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
