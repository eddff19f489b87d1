"""The node's name and topic names, in one place (ROS-free, so bags and offline replay share them).

Inputs are relative to the node's namespace; outputs starting with ``~/`` are private to the
node. Bags record absolute names (as ``ros2 bag record`` does): :func:`recorded`.
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
