"""Publishes a problem file's hypotheses on the node's input topics: the stand-in for ``ros2 topic pub``.

For every object ``<name>`` of the problem, a ``geometry_msgs/PoseArray`` on
``hypotheses/<name>`` (hypotheses in rank order, in the scene frame) and its weights on
``hypotheses/<name>/weights``, both relative to the publishing node's namespace.
Publishers use the default QoS (reliable, volatile, depth 10), like ``ros2 topic pub``.
"""

from __future__ import annotations

import time

from geometry_msgs.msg import PoseArray
from rclpy.node import Node
from rclpy.utilities import ok
from std_msgs.msg import Float64MultiArray

from physics_mapper.mapping.topics import poses_topic, weights_topic
from physics_mapper.model.scene import Problem
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs
from physics_mapper.ros.spinning import spin_once

QUEUE_DEPTH = 10


class HypothesisPublisher:
    """Publishers for one problem's hypotheses, created on ``node``."""

    def __init__(self, node: Node, problem: Problem) -> None:
        self.node = node
        self.problem = problem
        names = problem.scene.object_names
        self._poses = [node.create_publisher(PoseArray, poses_topic(name), QUEUE_DEPTH) for name in names]
        self._weights = [node.create_publisher(Float64MultiArray, weights_topic(name), QUEUE_DEPTH) for name in names]

    @property
    def topics(self) -> list[str]:
        """Resolved names of the PoseArray topics, in object order."""
        return [publisher.topic_name for publisher in self._poses]

    def wait_for_subscribers(self, timeout: float) -> bool:
        """Spin up to ``timeout`` seconds until every topic has a subscriber; True if they all do."""
        end = time.monotonic() + timeout
        publishers = self._poses + self._weights
        while any(p.get_subscription_count() == 0 for p in publishers):
            if time.monotonic() >= end or not ok():
                return False
            spin_once(self.node, 0.05)
        return True

    def publish(self) -> None:
        """Publish every object's PoseArray, then its weights, stamped now (exact integer nanoseconds)."""
        now_ns = self.node.get_clock().now().nanoseconds
        frame_id = self.problem.scene.frame_id
        for hypotheses, poses_pub, weights_pub in zip(self.problem.hypotheses, self._poses, self._weights, strict=True):
            poses, weights = hypotheses_msgs(hypotheses, frame_id=frame_id, stamp_ns=now_ns)
            poses_pub.publish(poses)
            weights_pub.publish(weights)
