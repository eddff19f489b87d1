"""Every rclpy shell: the node, its QoS, the hypothesis publisher, the bag player, the node as a child process.

The only room of ``physics_mapper`` that imports rclpy or a message package (with ``msg_adapters`` and the commands).
"""

from __future__ import annotations

from physics_mapper.ros.bag_player import (
    NEVER_BY_DEFAULT,
    RECORDER_QOS,
    Playback,
    ReplayError,
    message_class,
    play_and_record,
    played_topics,
)
from physics_mapper.ros.child_process import (
    node_command,
    start_node,
    stop_node,
)
from physics_mapper.ros.hypothesis_publisher import (
    HypothesisPublisher,
)
from physics_mapper.ros.node import (
    DEFAULT_DIAGNOSTICS_PERIOD,
    PARAMETERS,
    ParameterSpec,
    PhysicsMapperNode,
    deadline_first,
    main,
    resolve_scene_path,
)
from physics_mapper.ros.qos import (
    DIAGNOSTICS_QOS,
    INPUT_QOS,
    MAP_QOS,
    PLAYBACK_DEPTH,
    input_qos,
    playback_qos,
    qos_profile,
    recorded_qos,
)
from physics_mapper.ros.spinning import (
    STOP_POLL,
    STOP_SIGNALS,
    SignalStop,
    shutdown_ros,
    spin_for,
)

__all__ = [
    "DEFAULT_DIAGNOSTICS_PERIOD",
    "DIAGNOSTICS_QOS",
    "INPUT_QOS",
    "MAP_QOS",
    "NEVER_BY_DEFAULT",
    "PARAMETERS",
    "PLAYBACK_DEPTH",
    "RECORDER_QOS",
    "STOP_POLL",
    "STOP_SIGNALS",
    "HypothesisPublisher",
    "ParameterSpec",
    "PhysicsMapperNode",
    "Playback",
    "ReplayError",
    "SignalStop",
    "deadline_first",
    "input_qos",
    "main",
    "message_class",
    "node_command",
    "play_and_record",
    "playback_qos",
    "played_topics",
    "qos_profile",
    "recorded_qos",
    "resolve_scene_path",
    "shutdown_ros",
    "spin_for",
    "start_node",
    "stop_node",
]
