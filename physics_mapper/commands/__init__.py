"""The subcommands of ``physics-mapper``; each module has ``HELP``, ``add_arguments`` and ``run``.

Modules import ROS and matplotlib inside ``run``, so that ``--help`` and the ROS-free commands
start fast and work without rclpy.
"""

from __future__ import annotations

import importlib
from types import ModuleType

#: Subcommand names, each a module of this package, in the order ``--help`` lists them.
COMMANDS = ("solve", "generate", "replay", "node", "publish", "demo", "experiment", "bench")


def command_module(name: str) -> ModuleType:
    """The module of subcommand ``name``."""
    return importlib.import_module(f"physics_mapper.commands.{name}")


__all__ = ["COMMANDS", "command_module"]
