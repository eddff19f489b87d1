"""The subcommands of ``physics-mapper``; each module has ``HELP``, ``add_arguments`` and ``run``.

Modules import ROS and matplotlib inside ``run``, so that ``--help`` and the ROS-free commands
start fast and work without rclpy.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from types import ModuleType

from physics_mapper.core.scene import Problem
from physics_mapper.core.scene_files import load_problem

#: Subcommand names, each a module of this package, in the order ``--help`` lists them.
COMMANDS = ("solve", "generate", "replay", "node", "publish", "demo", "experiment", "bench")


def command_module(name: str) -> ModuleType:
    """The module of subcommand ``name``."""
    return importlib.import_module(f"physics_mapper.commands.{name}")


def load_problem_file(path: Path, command: str) -> Problem:
    """Load a problem file for subcommand ``command``; what loading changed goes to stderr as warnings."""
    problem = load_problem(path)
    for note in problem.notes:
        print(f"physics-mapper {command}: warning: {note}", file=sys.stderr)
    return problem


__all__ = ["COMMANDS", "command_module", "load_problem_file"]
