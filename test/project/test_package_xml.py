"""package.xml declares, with keys rosdep resolves, every library the installed package and its tests import.

``rosdep install --from-paths src --ignore-src`` installs what package.xml names; a missing or
misspelt key leaves a ROS machine without a library the node imports. Every import of the
installed Python package (``physics_mapper``) maps to an ``<exec_depend>``,
every import of the tests to an ``<exec_depend>`` or ``<test_depend>``, through :data:`PROVIDERS`;
the standard library and our own packages are exempt. Adding a library: add its row below and the
key to package.xml; the failure message says which.
"""

from __future__ import annotations

import ast
import re
import sys
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator
from pathlib import Path

from conftest import REPO

#: Top-level module -> the package.xml key that provides it. Keys are those of rosdistro's
#: rosdep/python.yaml (checked at ros/rosdistro commit 8468e88, August 2026): libraries packaged by
#: the distributions are ``python3-<name>``, pip-only ones ``python3-<name>-pip``. None: rosdistro
#: has no key (coacd, ray), so the library is pinned in requirements.txt (or an extra's requirements-<extra>.txt)
#: and installed with pip.
#: ROS packages (rclpy, ament_index_python, *_msgs, *_interfaces) are their own keys.
PROVIDERS: dict[str, str | None] = {
    "numpy": "python3-numpy",
    "yaml": "python3-yaml",
    "scipy": "python3-scipy",
    "matplotlib": "python3-matplotlib",
    "pybullet": "python3-pybullet-pip",
    "pybullet_data": "python3-pybullet-pip",
    "filterpy": "python3-filterpy-pip",
    "rosbags": "python3-rosbags-pip",
    "mcap": "mcap-ros2-support",  # no key of its own; this pip package requires mcap>=1.6.0
    "trimesh": "python3-trimesh-pip",
    "platformdirs": "python3-platformdirs",
    "psutil": "python3-psutil",
    "tqdm": "python3-tqdm",
    "hypothesis": "python3-hypothesis",
    "pytest": "python3-pytest",
    "coacd": None,
    "motmetrics": None,  # no key of its own found; pinned in requirements.txt
    "ray": None,
}
ROS_PACKAGES = {"rclpy", "ament_index_python", "rosidl_runtime_py", "launch", "launch_ros"}
#: The Python packages setup.py installs.
INSTALLED = ("physics_mapper",)
#: Their source folders: msg_adapters/ is installed as physics_mapper.msg_adapters.
SOURCE_FOLDERS = ("physics_mapper", "msg_adapters")
TESTS = REPO / "test"
BENCHMARKS = REPO / "benchmarks"


def is_ros_package(module: str) -> bool:
    return module in ROS_PACKAGES or module.endswith(("_msgs", "_interfaces"))


def imports(path: Path) -> Iterator[str]:
    """Top-level names of the absolute imports in ``path``, also in functions and ``importlib.import_module("x")``."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            yield from (alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module is not None and node.level == 0:
            yield node.module.split(".")[0]
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            yield node.args[0].value.split(".")[0]


def third_party_imports(files: list[Path], own: set[str]) -> dict[str, list[str]]:
    """Imported module -> the files importing it, without the standard library and ``own`` modules."""
    found: dict[str, list[str]] = {}
    for path in files:
        for module in set(imports(path)):
            if module not in sys.stdlib_module_names and module not in own:
                found.setdefault(module, []).append(str(path.relative_to(REPO)))
    return found


def declared(kind: str) -> set[str]:
    root = ElementTree.parse(REPO / "package.xml").getroot()
    return {element.text or "" for element in root.iter(kind)}


def key_of(module: str) -> str | None:
    return module if is_ros_package(module) else PROVIDERS[module]


def missing(found: dict[str, list[str]], allowed: set[str], tag: str) -> list[str]:
    """One line per imported module that package.xml does not provide, saying what to add."""
    problems = []
    for module, files in sorted(found.items()):
        where = f"{module} (imported by {', '.join(sorted(files)[:3])})"
        if not is_ros_package(module) and module not in PROVIDERS:
            problems.append(
                f"{where}: no row in PROVIDERS of test/project/test_package_xml.py; add its rosdep key from "
                f"rosdistro's rosdep/python.yaml (pip-only libraries end in -pip), then <{tag}>KEY</{tag}> to "
                "package.xml"
            )
        elif (key := key_of(module)) is not None and key not in allowed:
            problems.append(f"{where}: add <{tag}>{key}</{tag}> to package.xml")
    return problems


def installed_sources() -> list[Path]:
    """The installed package's modules and the launch files (installed to share/, run by ``ros2 launch``)."""
    modules = [path for folder in SOURCE_FOLDERS for path in (REPO / folder).rglob("*.py")]
    return sorted([*modules, *(REPO / "launch").glob("*.launch.py")])


def test_every_import_of_the_installed_package_is_an_exec_depend() -> None:
    found = third_party_imports(installed_sources(), set(INSTALLED))
    assert {"rclpy", "pybullet", "ray"} <= set(found)  # the walk sees function-level and importlib imports
    assert {"launch", "launch_ros", "lifecycle_msgs"} <= set(found)  # and the launch file's
    assert missing(found, declared("exec_depend"), "exec_depend") == []


def test_every_import_of_the_tests_is_a_test_or_exec_depend() -> None:
    files = sorted(TESTS.rglob("*.py"))
    # conftest, ros_helpers, ... and the benchmarks a test imports by name (benchmarks/ on sys.path)
    local = {path.stem for path in [*files, *BENCHMARKS.glob("*.py")]}
    found = third_party_imports(files, {*INSTALLED, *local})
    assert missing(found, declared("exec_depend") | declared("test_depend"), "test_depend") == []


def test_every_exec_depend_is_imported() -> None:
    """A stale key makes rosdep install what nothing uses (or fail on a key that no longer exists)."""
    used = {key_of(module) for module in third_party_imports(installed_sources(), set(INSTALLED))}
    assert sorted(declared("exec_depend") - used) == []


def test_libraries_without_a_rosdep_key_are_pinned_in_requirements() -> None:
    """In requirements.txt, or an optional extra's requirements-<extra>.txt (Ray)."""
    pinned = {
        match.group(1).lower()
        for path in REPO.glob("requirements*.txt")
        for line in path.read_text().splitlines()
        if (match := re.match(r"([A-Za-z0-9_.-]+)==", line.strip()))
    }
    found = third_party_imports(installed_sources(), set(INSTALLED))
    unkeyed = [module for module in found if not is_ros_package(module) and PROVIDERS.get(module, "") is None]
    assert [module for module in unkeyed if module not in pinned] == []


def test_a_missing_declaration_is_reported_with_the_key_to_add() -> None:
    found = {"pybullet": ["physics_mapper/physics/checker.py"], "trimesh_like": ["x.py"], "nav_msgs": ["y.py"]}
    problems = missing(found, {"python3-numpy"}, "exec_depend")
    assert problems == [
        "nav_msgs (imported by y.py): add <exec_depend>nav_msgs</exec_depend> to package.xml",
        "pybullet (imported by physics_mapper/physics/checker.py): add <exec_depend>python3-pybullet-pip</exec_depend> "
        "to package.xml",
        "trimesh_like (imported by x.py): no row in PROVIDERS of test/project/test_package_xml.py; add its rosdep key "
        "from rosdistro's rosdep/python.yaml (pip-only libraries end in -pip), then <exec_depend>KEY</exec_depend> to "
        "package.xml",
    ]
