"""rclpy context and spinning helpers shared by the node, the publisher and the bag player."""

from __future__ import annotations

import time

import rclpy
from rclpy.node import Node
from rclpy.utilities import ok


def shutdown_ros() -> None:
    """Shut rclpy down unless a signal (SIGINT, SIGTERM) already did."""
    if ok():
        rclpy.shutdown()


def spin_for(node: Node, seconds: float) -> None:
    """Handle ``node``'s events for ``seconds`` (less if rclpy shuts down)."""
    end = time.monotonic() + seconds
    while ok() and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
