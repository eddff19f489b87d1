"""The node's ROS-free logic: input rules, one map-building tick, topic names and integer-nanosecond stamps.

What the rclpy shell (:mod:`physics_mapper.ros.node`) runs between its subscriptions and publishers.
"""

from __future__ import annotations

from physics_mapper.mapping.inputs import (
    WEIGHTS_GRACE,
    InputSettings,
    InputSnapshot,
    InputTracker,
    InUse,
    Level,
    ObjectInputs,
    ObjectStatus,
    ReceivedPoses,
    ReceivedWeights,
    check_poses,
    check_weights,
    rank,
)
from physics_mapper.mapping.mapper import (
    DEADLINE_SLACK,
    DEFAULT_RATE_HZ,
    Mapper,
    MapperSettings,
    TickReport,
    mapper_settings_problem,
)
from physics_mapper.mapping.stamps import (
    NANOSECONDS_PER_SECOND,
    time_parts,
    to_nanoseconds,
)
from physics_mapper.mapping.topics import (
    CONFIGURATION_TOPIC,
    DIAGNOSTICS_TOPIC,
    GROUND_TRUTH_TOPIC,
    MARKERS_TOPIC,
    NODE_NAME,
    RECORDED_CONFIGURATION_TOPIC,
    RECORDED_MARKERS_TOPIC,
    RECORDED_SETTLED_TOPIC,
    SETTLED_TOPIC,
    output_topic,
    poses_topic,
    recorded,
    recorded_poses_topic,
    recorded_weights_topic,
    weights_topic,
)

__all__ = [
    "CONFIGURATION_TOPIC",
    "DEADLINE_SLACK",
    "DEFAULT_RATE_HZ",
    "DIAGNOSTICS_TOPIC",
    "GROUND_TRUTH_TOPIC",
    "MARKERS_TOPIC",
    "NANOSECONDS_PER_SECOND",
    "NODE_NAME",
    "RECORDED_CONFIGURATION_TOPIC",
    "RECORDED_MARKERS_TOPIC",
    "RECORDED_SETTLED_TOPIC",
    "SETTLED_TOPIC",
    "WEIGHTS_GRACE",
    "InUse",
    "InputSettings",
    "InputSnapshot",
    "InputTracker",
    "Level",
    "Mapper",
    "MapperSettings",
    "ObjectInputs",
    "ObjectStatus",
    "ReceivedPoses",
    "ReceivedWeights",
    "TickReport",
    "check_poses",
    "check_weights",
    "mapper_settings_problem",
    "output_topic",
    "poses_topic",
    "rank",
    "recorded",
    "recorded_poses_topic",
    "recorded_weights_topic",
    "time_parts",
    "to_nanoseconds",
    "weights_topic",
]
