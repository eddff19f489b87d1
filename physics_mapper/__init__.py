"""physics_mapper: physically consistent multi-object maps from weighted pose hypotheses (Wagle & Correll 2010).

Rooms, data flowing one way (messages -> ``msg_adapters`` -> ``mapping`` -> ``core`` and back):

* ``core``: ROS-free scene model, the two physics rules in pybullet, the branch-and-bound search;
* ``mapping``: the node's ROS-free logic (input rules, one tick, topic names);
* ``ros``: the rclpy shells (the node, the publisher, the bag player);
* ``bags``: rosbag2 I/O and offline evaluation; ``perception``: the simulated particle filters;
* ``experiments``: the paper's figures; ``bench``: cost measurements;
* ``commands`` and ``cli``: the ``physics-mapper`` command line.

The top-level ``msg_adapters`` package converts ROS messages to these types and back.
"""
