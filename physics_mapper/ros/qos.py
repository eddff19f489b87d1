"""The node's QoS profiles as rclpy ``QoSProfile`` objects, made from :mod:`physics_mapper.mapping.topics`' table;
and QoS between the ROS graph and rosbag2's recorded ``offered_qos_profiles`` (rosbags' ``Qos``).

Light to import (no physics): the node, the publisher, the bag player and the tests share it.
"""

from __future__ import annotations

from collections.abc import Sequence

from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.topics import (
    DIAGNOSTICS_TOPIC_QOS,
    MAP_TOPIC_QOS,
    TF_STATIC_TOPIC_QOS,
    TF_TOPIC_QOS,
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
TF_QOS = qos_profile(TF_TOPIC_QOS)
TF_STATIC_QOS = qos_profile(TF_STATIC_TOPIC_QOS)


#: Keep-last depth of a replay's volatile publishers and of its recorder (a burst of a bag's messages).
PLAYBACK_DEPTH = 100


def _qos_time(duration: Duration) -> QosTime:
    return QosTime(*divmod(duration.nanoseconds, NANOSECONDS_PER_SECOND))


def recorded_qos(profile: QoSProfile) -> Qos:
    """A publisher's profile (from the ROS graph) as rosbag2 records it in ``offered_qos_profiles``."""
    return Qos(
        history=QosHistory(int(profile.history)),
        depth=profile.depth,
        reliability=QosReliability(int(profile.reliability)),
        durability=QosDurability(int(profile.durability)),
        deadline=_qos_time(profile.deadline),
        lifespan=_qos_time(profile.lifespan),
        liveliness=QosLiveliness(int(profile.liveliness)),
        liveliness_lease_duration=_qos_time(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions,
    )


def playback_qos(offered: Sequence[Qos]) -> QoSProfile:
    """The profile a replay publishes a topic with, from the profiles its publishers offered when recorded.

    As ``ros2 bag play`` does: the recorded reliability and durability when every recorded
    publisher offered the same (a latched topic stays latched: late subscribers get its last
    messages), else reliable and volatile, which every subscriber accepts. Depth: for transient
    local the recorded one (how many messages a late subscriber gets; the ROS graph does not tell
    it, so a recording from the graph holds 0: then 1, the last message), else :data:`PLAYBACK_DEPTH`.
    """
    kinds = {(q.reliability, q.durability) for q in offered}
    if len(kinds) != 1:
        return qos_profile(TopicQos(reliable=True, transient_local=False, depth=PLAYBACK_DEPTH))
    ((reliability, durability),) = kinds
    transient_local = durability == QosDurability.TRANSIENT_LOCAL
    depth = max(q.depth for q in offered) if transient_local else PLAYBACK_DEPTH
    return qos_profile(TopicQos(reliability != QosReliability.BEST_EFFORT, transient_local, max(depth, 1)))
