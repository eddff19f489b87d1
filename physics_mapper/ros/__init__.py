"""Every rclpy shell: the node, its QoS, the hypothesis publisher, the bag player, the node as a child process.

The only room of ``physics_mapper`` that imports rclpy or a message package (with ``msg_adapters`` and the commands).
"""
