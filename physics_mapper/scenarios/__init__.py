"""Seeded problem suites and generators shared by the tests, the benchmarks and ``generate`` (ROS-free)."""
