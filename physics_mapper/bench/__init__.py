"""What the core costs on this machine (ROS-free): the physics checks and the search, timed side by side."""

from __future__ import annotations

from physics_mapper.bench.physics_costs import (
    PhysicsCosts,
    costs_text,
    measure,
    median_seconds,
)
from physics_mapper.bench.problems import (
    COLUMN_SPACING,
    floating_problem,
)

__all__ = [
    "COLUMN_SPACING",
    "PhysicsCosts",
    "costs_text",
    "floating_problem",
    "measure",
    "median_seconds",
]
