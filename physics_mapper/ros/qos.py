"""The node's QoS profiles as rclpy ``QoSProfile`` objects, made from :mod:`physics_mapper.mapping.topics`' table.

Light to import (no physics): the node, the publisher, the demo and the tests share it.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from physics_mapper.mapping.topics import (
    DIAGNOSTICS_TOPIC_QOS,
    MAP_TOPIC_QOS,
    InputReliability,
    TopicQos,
    input_topic_qos,
)


def qos_profile(qos: TopicQos) -> QoSProfile:
    """The rclpy profile of a topic's QoS (keep last ``depth``)."""
    return QoSProfile(  # type: ignore[no-untyped-call]  # QoSProfile.__init__ is unannotated in rclpy 7
        history=HistoryPolicy.KEEP_LAST,
        depth=qos.depth,
        reliability=ReliabilityPolicy.RELIABLE if qos.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if qos.transient_local else DurabilityPolicy.VOLATILE,
    )


def input_qos(reliability: InputReliability = "best_effort") -> QoSProfile:
    """The hypothesis subscriptions' profile for the node's ``input_reliability`` parameter."""
    return qos_profile(input_topic_qos(reliability))


INPUT_QOS = input_qos()
MAP_QOS = qos_profile(MAP_TOPIC_QOS)
DIAGNOSTICS_QOS = qos_profile(DIAGNOSTICS_TOPIC_QOS)
