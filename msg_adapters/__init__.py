"""ROS messages <-> core types, and nothing else: hypotheses in, maps, markers and diagnostics out."""

from __future__ import annotations

from msg_adapters.diagnostics import (
    diagnostics_msg,
    search_values,
    tick_values,
)
from msg_adapters.hypotheses import (
    hypotheses_msgs,
    nanoseconds_from_stamp,
    pose_array_msg,
    pose_msg,
    raw_pose,
    received_pose_array,
    received_poses,
    received_weights,
    stamp_from_nanoseconds,
    weights_msg,
)
from msg_adapters.pose_array_cdr import (
    PoseArrayView,
    pose_array_view,
)
from msg_adapters.results import (
    FALLBACK_COLOR,
    LABEL_COLOR,
    LABEL_HEIGHT,
    LABEL_NAMESPACE,
    PLANE_MARKER_SIZE,
    SHAPE_NAMESPACE,
    STATIC_COLOR,
    STATIC_NAMESPACE,
    VALID_COLOR,
    configuration_msgs,
    markers_msg,
    object_pose_msgs,
    static_markers_msg,
)

__all__ = [
    "FALLBACK_COLOR",
    "LABEL_COLOR",
    "LABEL_HEIGHT",
    "LABEL_NAMESPACE",
    "PLANE_MARKER_SIZE",
    "SHAPE_NAMESPACE",
    "STATIC_COLOR",
    "STATIC_NAMESPACE",
    "VALID_COLOR",
    "PoseArrayView",
    "configuration_msgs",
    "diagnostics_msg",
    "hypotheses_msgs",
    "markers_msg",
    "nanoseconds_from_stamp",
    "object_pose_msgs",
    "pose_array_msg",
    "pose_array_view",
    "pose_msg",
    "raw_pose",
    "received_pose_array",
    "received_poses",
    "received_weights",
    "search_values",
    "stamp_from_nanoseconds",
    "static_markers_msg",
    "tick_values",
    "weights_msg",
]
