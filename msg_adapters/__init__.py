"""ROS messages <-> core types, and nothing else: hypotheses in, maps, markers and diagnostics out."""
