"""The node's ROS-free logic: input rules, one map-building tick, topic names and integer-nanosecond stamps.

What the rclpy shell (:mod:`physics_mapper.ros.node`) runs between its subscriptions and publishers.
"""
