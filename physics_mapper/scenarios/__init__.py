"""Seeded problem suites and generators, with their known answers, shared by the tests and the benchmarks (ROS-free)."""
