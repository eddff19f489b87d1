"""The tree is the architecture: which room may import what, checked statically and at run time.

Rooms are the subpackages of ``physics_mapper``. Only ``ros/``, ``msg_adapters/`` and
``commands/`` may import rclpy or a ROS package; ``model/`` imports no
other room, ``physics/`` only the model, ``search/`` the model and the physics; every room imports
only the rooms :data:`ALLOWED` names, so data flows one way: messages -> msg_adapters -> mapping ->
model/physics/search -> mapping -> msg_adapters -> messages.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import PROBLEMS, REPO

#: Room -> the other rooms it may import from (``cli``: the top-level modules of ``physics_mapper``;
#: ``api``: its ``__init__``, the public Python names).
ALLOWED: dict[str, set[str]] = {
    "model": set(),
    "physics": {"model"},
    "search": {"model", "physics"},
    "perception": {"model", "physics"},
    "mapping": {"model", "physics", "search"},
    "bags": {"model", "mapping"},
    "scenarios": {"model", "physics", "search"},
    "evaluation": {"model", "physics", "search", "mapping", "bags"},
    "experiments": {"model", "physics", "search", "perception", "evaluation"},
    "msg_adapters": {"model", "search", "mapping"},
    "ros": {"model", "search", "mapping", "bags", "evaluation", "msg_adapters"},
    "commands": {
        "model",
        "physics",
        "search",
        "mapping",
        "bags",
        "perception",
        "scenarios",
        "evaluation",
        "experiments",
        "msg_adapters",
        "ros",
    },
    "cli": {"model", "commands"},
    "api": {"model", "physics", "search"},
}
#: Rooms that may import ROS: rclpy, message packages and the other ROS 2 Python packages.
ROS_ROOMS = {"ros", "msg_adapters", "commands"}
#: ``ament_index_python`` is a pure-Python file lookup (no messages, no middleware): the model finds
#: ``package://`` files with it, so it is not among them.
ROS_PACKAGES = {"rclpy", "rmw", "rcl_interfaces", "builtin_interfaces"}
#: ``msg_adapters/`` is a room at the top level, installed as ``physics_mapper.msg_adapters`` (setup.py);
#: ``physics_mapper/msg_adapters`` is a link to it, which ``rglob`` does not follow.
SOURCES = sorted([*(REPO / "physics_mapper").rglob("*.py"), *(REPO / "msg_adapters").rglob("*.py")])


def is_ros_package(module: str) -> bool:
    top_level = module.split(".")[0]
    return top_level in ROS_PACKAGES or top_level.endswith("_msgs") or top_level.startswith("rosidl")


def room_of(path: Path) -> str:
    """The room of a source file: its subpackage of physics_mapper (or msg_adapters), or cli for top-level modules."""
    parts = path.relative_to(REPO).parts
    if parts[0] == "msg_adapters":
        return "msg_adapters"
    if parts[1:] == ("__init__.py",):
        return "api"
    return parts[1] if len(parts) > 2 else "cli"


def imported_modules(path: Path) -> Iterator[str]:
    """Every module a file imports, at any depth (imports inside functions too)."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module is not None:
            yield node.module


def room_imported(module: str) -> str | None:
    """The room an imported module belongs to, or None for a module outside the project."""
    parts = module.split(".")
    if parts[0] != "physics_mapper":
        return None
    return parts[1] if len(parts) > 1 and parts[1] in ALLOWED else "cli"


def violations(path: Path) -> list[str]:
    """What ``path`` imports that its room may not."""
    room, found = room_of(path), []
    for module in imported_modules(path):
        if is_ros_package(module) and room not in ROS_ROOMS:
            found.append(f"{path.relative_to(REPO)} ({room}) imports ROS package {module}")
        target = room_imported(module)
        if target is not None and target != room and target not in ALLOWED[room]:
            found.append(f"{path.relative_to(REPO)} ({room}) imports {module} of room {target}")
    return found


def test_every_source_file_is_in_a_known_room() -> None:
    assert {room_of(path) for path in SOURCES} == set(ALLOWED)


def test_msg_adapters_is_at_the_top_level_and_linked_into_the_package() -> None:
    link = REPO / "physics_mapper" / "msg_adapters"
    assert (REPO / "msg_adapters" / "__init__.py").is_file()
    assert link.is_symlink() and link.resolve() == (REPO / "msg_adapters").resolve()


@pytest.mark.parametrize("path", SOURCES, ids=lambda path: str(path.relative_to(REPO)))
def test_imports_stay_inside_the_allowed_rooms(path: Path) -> None:
    assert violations(path) == []


@pytest.mark.parametrize(
    "line", ["import rclpy", "from geometry_msgs.msg import Pose", "from physics_mapper.mapping import topics"]
)
def test_a_forbidden_import_in_the_model_is_found(line: str) -> None:
    probe = REPO / "physics_mapper" / "model" / "_layout_probe.py"
    probe.write_text(f"def load() -> None:\n    {line}\n")
    try:
        assert len(violations(probe)) == 1
    finally:
        probe.unlink()


#: Every module of the ROS-free rooms, by dotted name (``__main__`` runs the CLI when imported).
ROS_FREE_MODULES = tuple(
    ".".join(path.relative_to(REPO).with_suffix("").parts).removesuffix(".__init__")
    for path in SOURCES
    if room_of(path) not in ROS_ROOMS and path.name != "__main__.py"
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


def test_ros_free_modules_and_solve_load_no_ros_module() -> None:
    report = probe(ROS_FREE_MODULES)
    assert report["loaded"] == sorted(ROS_FREE_MODULES)
    assert report["ros"] == []


def test_the_probe_sees_ros_modules_when_they_are_imported() -> None:
    report = probe((*ROS_FREE_MODULES, "rclpy", "geometry_msgs.msg"))
    assert {"rclpy", "geometry_msgs"} <= set(report["ros"])


def test_the_allowed_room_graph_has_no_cycle() -> None:
    """Data flows one way: no room may (through others) import a room that imports it."""
    state: dict[str, str] = {}

    def visit(room: str, path: tuple[str, ...]) -> None:
        assert state.get(room) != "open", f"cycle: {' -> '.join((*path, room))}"
        if state.get(room) == "done":
            return
        state[room] = "open"
        for other in sorted(ALLOWED[room]):
            visit(other, (*path, room))
        state[room] = "done"

    for room in sorted(ALLOWED):
        visit(room, ())
