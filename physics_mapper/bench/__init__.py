"""What the core costs on this machine (ROS-free): the physics checks and the search, timed side by side."""
