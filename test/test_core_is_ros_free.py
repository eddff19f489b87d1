"""The core imports and solves without ROS: no rclpy, no message package, in a fresh interpreter."""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

from conftest import PROBLEMS

CORE_MODULES = (
    "physics_mapper.geometry",
    "physics_mapper.hypotheses",
    "physics_mapper.scene",
    "physics_mapper.physics",
    "physics_mapper.search",
    "physics_mapper.report",
    "physics_mapper.errors",
    "physics_mapper.topics",
    "physics_mapper.stamps",
    "physics_mapper.bench",
    "physics_mapper.inputs",
    "physics_mapper.mapper",
    "physics_mapper.particle_filter",
    "physics_mapper.bags",
    "physics_mapper.replay",
    "physics_mapper.scoring",
    "physics_mapper.experiments.fig4",
    "physics_mapper.experiments.fig6",
    "physics_mapper.experiments.fig8",
    "physics_mapper.experiments.peg",
    "physics_mapper.cli",
    "physics_mapper.commands.solve",
)

# Imports the given modules, solves a shipped problem through the CLI's own main(), and
# reports the ROS packages then loaded (top-level names of sys.modules).
PROBE = """
import contextlib, importlib, io, json, sys
for name in {modules!r}:
    importlib.import_module(name)
from physics_mapper.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    status = main(["solve", {problem!r}, "--json"])
roots = {{name.split(".")[0] for name in sys.modules}}
ros = sorted(r for r in roots if r in ("rclpy", "rmw") or r.endswith("_msgs") or r.startswith("rosidl"))
print(json.dumps({{"status": status, "ros": ros, "loaded": sorted(set({modules!r}) & set(sys.modules))}}))
"""


def probe(modules: tuple[str, ...]) -> dict[str, Any]:
    """Run :data:`PROBE` in a fresh interpreter and return its report."""
    code = PROBE.format(modules=modules, problem=str(PROBLEMS / "stack.yaml"))
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert completed.returncode == 0, completed.stderr
    report: dict[str, Any] = json.loads(completed.stdout)
    assert report["status"] == 0
    return report


def test_core_modules_and_solve_load_no_ros_module() -> None:
    report = probe(CORE_MODULES)
    assert report["loaded"] == sorted(CORE_MODULES)
    assert report["ros"] == []


def test_the_probe_sees_ros_modules_when_they_are_imported() -> None:
    report = probe((*CORE_MODULES, "rclpy", "geometry_msgs.msg"))
    assert {"rclpy", "geometry_msgs"} <= set(report["ros"])
