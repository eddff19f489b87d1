"""Simulated perception (ROS-free): a particle filter per object turns noisy measurements into weighted hypotheses."""
