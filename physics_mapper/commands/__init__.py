"""The subcommands of ``physics-mapper``; each module has ``HELP``, ``add_arguments`` and ``run``.

Modules import ROS and matplotlib inside ``run``, so that ``--help`` and the ROS-free commands
start fast and work without rclpy. This package itself imports nothing heavy: the node's entry
point (:func:`physics_mapper.commands.node.main`) must run its first line before numpy starts
threads (see ``hold_stop_signals``). Shared helpers are in :mod:`physics_mapper.commands.files`.
"""

from __future__ import annotations

import importlib
from types import ModuleType

#: Subcommand names, each a module of this package, in the order ``--help`` lists them.
COMMANDS = (
    "solve",
    "generate",
    "replay",
    "evaluate",
    "sweep",
    "node",
    "publish",
    "demo",
    "experiment",
    "bench",
    "decompose",
)


def command_module(name: str) -> ModuleType:
    """The module of subcommand ``name``."""
    return importlib.import_module(f"physics_mapper.commands.{name}")


__all__ = ["COMMANDS", "command_module"]
