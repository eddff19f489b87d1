"""The node's QoS profiles and rclpy helpers (topic names are in :mod:`physics_mapper.mapping.topics`).

Light to import (no physics): the node, the publisher, the demo and the tests share it.

QoS: inputs are best effort, volatile, depth 10, which matches both reliable publishers
(``ros2 topic pub``, most pose estimators) and best-effort ones (sensor-data QoS); the map
topics are reliable and transient local, depth 1 (latched), so RViz or a recorder started
later still gets the last map; ``/diagnostics`` uses the default QoS, like diagnostic_updater.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

# QoSProfile.__init__ is unannotated in rclpy 7.
INPUT_QOS = QoSProfile(  # type: ignore[no-untyped-call]
    depth=10, reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE
)
MAP_QOS = QoSProfile(  # type: ignore[no-untyped-call]
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
DIAGNOSTICS_QOS = QoSProfile(depth=10)  # type: ignore[no-untyped-call]
