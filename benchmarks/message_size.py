"""How large a PoseArray arrives reliably on the node's input QoS; is every loss reported?

A child process publishes ``--messages`` PoseArrays of each size at ``--hz`` with a reliable
publisher (as ``ros2 topic pub`` and most pose estimators do); this process subscribes as the
node does (raw, with the middleware's message-lost event), once with the default best-effort
input QoS and once with ``input_reliability: reliable``, and counts what arrived and what the
middleware reported lost. The subscriber is idle, so nothing is lost to a busy executor: the
figures are the transport's (Fast DDS on loopback here). Run:

    .venv/bin/python benchmarks/message_size.py [--messages 50] [--hz 10]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time

import rclpy
from geometry_msgs.msg import PoseArray
from live_node import isolate_ros, load_average
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.qos import QoSProfile

from physics_mapper.mapping.topics import INPUT_RELIABILITIES, InputReliability
from physics_mapper.model.geometry import Pose
from physics_mapper.msg_adapters.hypotheses import pose_array_msg
from physics_mapper.ros.qos import input_qos

SIZES = (1_000, 2_000, 5_000, 10_000, 20_000, 50_000)
TOPIC = "/message_size/hypotheses"
#: Seconds the publisher waits once it sees the subscriber (the subscriber side matches a moment later),
#: and after its last message (reliable delivery completes).
SETTLE = 1.0


def publish(poses: int, count: int, hz: float) -> None:
    """The child process: ``count`` PoseArrays of ``poses`` poses at ``hz``, reliable, depth 10."""
    rclpy.init()
    node = rclpy.create_node("message_size_publisher")
    publisher = node.create_publisher(PoseArray, TOPIC, QoSProfile(depth=10))  # type: ignore[no-untyped-call]
    message = pose_array_msg([Pose((0.0, 0.0, 0.1 + 1e-6 * i)) for i in range(poses)], frame_id="world", stamp_ns=1)
    while publisher.get_subscription_count() == 0:
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(SETTLE)
    for _ in range(count):
        publisher.publish(message)
        time.sleep(1.0 / hz)
    time.sleep(SETTLE)
    rclpy.shutdown()


def measure(poses: int, reliability: InputReliability, count: int, hz: float) -> tuple[int, int]:
    """(received, reported lost) of ``count`` messages of ``poses`` poses on the node's input QoS."""
    rclpy.init()
    node = rclpy.create_node("message_size_subscriber")
    received, lost = [0], [0]

    def on_lost(info: QoSMessageLostInfo) -> None:
        lost[0] += int(info.total_count_change)

    def on_message(raw: bytes) -> None:
        received[0] += 1

    node.create_subscription(
        PoseArray,
        TOPIC,
        on_message,
        input_qos(reliability),
        event_callbacks=SubscriptionEventCallbacks(message_lost=on_lost),
        raw=True,
    )
    command = [sys.executable, __file__, "--publish", str(poses), "--messages", str(count), "--hz", str(hz)]
    publisher = subprocess.Popen(command)
    while publisher.poll() is None:
        rclpy.spin_once(node, timeout_sec=0.05)
    end = time.monotonic() + 0.5
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    node.destroy_node()  # type: ignore[no-untyped-call]
    rclpy.shutdown()
    return received[0], lost[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--messages", type=int, default=50, help="messages per size and QoS (default 50)")
    parser.add_argument("--hz", type=float, default=10.0, help="messages per second (default 10)")
    parser.add_argument("--publish", type=int, metavar="POSES", help=argparse.SUPPRESS)
    args = parser.parse_args()
    isolate_ros()
    if args.publish is not None:
        publish(args.publish, args.messages, args.hz)
        return
    print(f"load average: {load_average()}; {args.messages} messages per row at {args.hz:g} Hz, reliable publisher")
    print("| poses | kB | " + " | ".join(f"{r}: received / reported lost" for r in INPUT_RELIABILITIES) + " |")
    print("| ---: | ---: | ---: | ---: |")
    for poses in SIZES:
        size = 56 * poses / 1024
        cells = [measure(poses, reliability, args.messages, args.hz) for reliability in INPUT_RELIABILITIES]
        print(f"| {poses} | {size:.0f} | " + " | ".join(f"{r} / {lost}" for r, lost in cells) + " |", flush=True)


if __name__ == "__main__":
    main()
