"""rosbag2 bags, read and written with ``rosbags`` (ROS-free): mcap and sqlite3 storage, read-ahead.

What a bag's messages mean (snapshots, evaluation) is :mod:`physics_mapper.evaluation`'s.
"""
