"""Subcommands of ``physics-mapper``; each module has ``HELP``, ``add_arguments`` and ``run``.

Modules import heavy or ROS dependencies inside ``run`` so that ``--help`` and the
ROS-free commands start fast and work without rclpy.
"""
