"""Shared by the benchmarks that run the node over DDS: a ROS domain of their own, the busy problem, process memory.

Not a benchmark itself. The node runs in a child process (``physics_mapper.ros.child_process``)
or in the benchmark's process; everything talks on loopback in its own ``ROS_DOMAIN_ID``.
"""

from __future__ import annotations

import os
import statistics
from collections.abc import Sequence
from pathlib import Path

from physics_mapper.model.scene import Problem
from physics_mapper.model.scene_files import load_scene
from physics_mapper.ros.node_memory import resident_set_size
from physics_mapper.scenarios.problems import floating_problem

REPO = Path(__file__).resolve().parent.parent
PYRAMID_SCENE = REPO / "config" / "scenes" / "pyramid.yaml"
PYRAMID_PROBLEM = REPO / "config" / "problems" / "pyramid.yaml"


#: Set by the benchmark that chose the domain, so that its child processes keep it.
DOMAIN_MARK = "PHYSICS_MAPPER_BENCHMARK_DOMAIN"


def isolate_ros() -> None:
    """Talk on a ROS domain of this benchmark alone, on loopback; its children (which call this too) keep it."""
    if os.environ.get(DOMAIN_MARK) is None or os.environ.get(DOMAIN_MARK) != os.environ.get("ROS_DOMAIN_ID"):
        os.environ["ROS_DOMAIN_ID"] = os.environ[DOMAIN_MARK] = str(120 + os.getpid() % 100)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")


def busy_problem(per_object: int = 60) -> Problem:
    """The pyramid's cubes floating apart, ``per_object`` hypotheses each: every search runs to its deadline."""
    return floating_problem(load_scene(PYRAMID_SCENE), per_object)


def memory_mb(pid: int) -> float:
    """A process's resident memory now, in MiB."""
    return resident_set_size(pid) / 2**20


def percentile(values: Sequence[float], fraction: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(fraction * (len(ordered) - 1)))] if ordered else float("nan")


def spread(values: Sequence[float]) -> str:
    """Median, 99th percentile and maximum, as ``a / b / c``."""
    if not values:
        return "-"
    return f"{statistics.median(values):.1f} / {percentile(values, 0.99):.1f} / {max(values):.1f}"


def load_average() -> str:
    return " ".join(f"{load:.2f}" for load in os.getloadavg())
