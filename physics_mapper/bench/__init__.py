"""What the core costs on this machine (ROS-free): the physics checks and the search, timed side by side."""

from __future__ import annotations

from physics_mapper.bench.physics_costs import (
    PhysicsCosts,
    costs_text,
    measure,
    median_seconds,
)

__all__ = [
    "PhysicsCosts",
    "costs_text",
    "measure",
    "median_seconds",
]
