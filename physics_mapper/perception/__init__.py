"""Simulated perception (ROS-free): a particle filter per object turns noisy measurements into weighted hypotheses."""

from __future__ import annotations

from physics_mapper.perception.particle_filter import (
    GROUND_TRUTH_SETTLE_TIME,
    TrackerSettings,
    run_generators,
    settle_ground_truth,
    track,
    tracker_settings_problem,
)

__all__ = [
    "GROUND_TRUTH_SETTLE_TIME",
    "TrackerSettings",
    "run_generators",
    "settle_ground_truth",
    "track",
    "tracker_settings_problem",
]
