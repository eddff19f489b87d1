"""The node's input subscriptions: every scene object's hypotheses, and ``detections`` where vision_msgs is installed.

Each subscription's callback gets the message info (the time the middleware received the message);
the per-object subscriptions also count the middleware's lost messages. Topic names are resolved
by the node (namespace, remaps), and an object name that cannot be part of a topic name is one
clear error.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, cast

from geometry_msgs.msg import PoseArray
from rclpy.callback_groups import CallbackGroup
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.exceptions import InvalidTopicNameException
from rclpy.node import Node
from rclpy.subscription import Subscription
from std_msgs.msg import Float64MultiArray

from physics_mapper.mapping.detections import DETECTIONS_TOPIC
from physics_mapper.mapping.inputs import MESSAGE_KINDS
from physics_mapper.mapping.topics import InputReliability, poses_topic, weights_topic
from physics_mapper.model.errors import InputError
from physics_mapper.ros.node_inputs import InputHandlers
from physics_mapper.ros.qos import input_qos


@dataclass
class InputSubscriptions:
    """Creates the node's input subscriptions in one callback group, with one reliability."""

    node: Node
    handlers: InputHandlers
    reliability: InputReliability
    group: CallbackGroup
    made: list[Subscription]

    def objects(self, names: tuple[str, ...] | list[str]) -> list[str]:
        """Subscribe to each object's hypotheses; the topics' names as resolved."""
        return [topic for name in names for topic in self._object(name)]

    def _object(self, name: str) -> list[str]:
        topics = [
            (PoseArray, poses_topic(name), self.handlers.poses(name)),
            (Float64MultiArray, weights_topic(name), self.handlers.weights(name)),
        ]
        try:
            return [
                self._subscribe(msg_type, topic, callback, self.handlers.lost(name, kind), raw=kind == "poses")
                for (msg_type, topic, callback), kind in zip(topics, MESSAGE_KINDS, strict=True)
            ]
        except InvalidTopicNameException:
            raise InputError(f"object name {name!r} cannot be part of a ROS topic name") from None

    def detections(self) -> list[str]:
        """Subscribe to ``detections`` (``vision_msgs/Detection3DArray``) where vision_msgs is installed: its
        results are the hypotheses of the objects their class ids name (:mod:`physics_mapper.mapping.detections`)."""
        try:
            from vision_msgs.msg import Detection3DArray
        except ImportError:
            return []
        # A lost array cannot be laid to one object: the middleware's losses are not counted for it.
        # Subscribed serialised, as the poses are: read without a Python object per result.
        handler = self.handlers.detections(Detection3DArray)
        return [self._subscribe(Detection3DArray, DETECTIONS_TOPIC, handler, raw=True)]

    def _subscribe(
        self,
        msg_type: type,
        topic: str,
        callback: Callable[[Any, Mapping[str, Any]], None],
        lost: Callable[[QoSMessageLostInfo], None] | None = None,
        *,
        raw: bool = False,
    ) -> str:
        subscription = self.node.create_subscription(
            msg_type,
            topic,
            cast(Callable[[Any], None], callback),  # rclpy passes two-parameter callbacks the message info
            input_qos(self.reliability),
            callback_group=self.group,
            event_callbacks=None if lost is None else SubscriptionEventCallbacks(message_lost=lost),
            raw=raw,
        )
        self.made.append(subscription)
        return str(subscription.topic_name)
