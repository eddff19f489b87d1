"""The launch file names only what exists: executables of this package, its node's parameters, shipped files.

``launch`` and ``launch_ros`` are not installable from PyPI, so the file is read, not run: every
``Node``/``LifecycleNode`` executable must be a console script setup.py installs for ``ros2 run``,
every parameter the node is given must be one it declares, and the default files must be shipped.
"""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

from conftest import REPO, not_sources

from physics_mapper.ros.parameters import PARAMETERS, RCLPY_PARAMETERS

LAUNCH = REPO / "launch" / "physics_mapper.launch.py"


def calls(name: str) -> list[ast.Call]:
    tree = ast.parse(LAUNCH.read_text())
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", None) == name]


def keyword(call: ast.Call, name: str) -> ast.expr:
    return next(k.value for k in call.keywords if k.arg == name)


def constant(expr: ast.expr) -> object:
    """A literal, or the value of a module-level NAME = literal of the launch file."""
    if isinstance(expr, ast.Name):
        tree = ast.parse(LAUNCH.read_text())
        assigned = {
            target.id: node.value
            for node in tree.body
            if isinstance(node, ast.Assign)
            for target in node.targets
            if isinstance(target, ast.Name)
        }
        return ast.literal_eval(assigned[expr.id])
    return ast.literal_eval(expr)


def ros_run_executables() -> set[str]:
    """The scripts setup.py installs for ``ros2 run`` (data files of lib/physics_mapper, for every build)."""
    (listed,) = re.findall(r"ROS2_RUN_SCRIPTS = \(([^)]*)\)", (REPO / "setup.py").read_text())
    scripts = {Path(path).name for path in ast.literal_eval(f"({listed})")}
    assert all((REPO / "scripts" / name).is_file() for name in scripts)
    return scripts


def node_keywords() -> dict[str, ast.expr]:
    """The keywords both node actions share (the ``node`` dict they are given as ``**node``)."""
    tree = ast.parse(LAUNCH.read_text())
    (shared,) = [
        n.value
        for n in ast.walk(tree)
        if isinstance(n, ast.Assign) and [getattr(t, "id", None) for t in n.targets] == ["node"]
    ]
    assert isinstance(shared, ast.Dict)
    return {str(constant(k)): v for k, v in zip(shared.keys, shared.values, strict=True) if k is not None}


def test_every_executable_it_starts_is_installed_for_ros2_run() -> None:
    nodes = calls("Node") + calls("LifecycleNode")
    executables = {constant(keyword(call, "executable")) for call in nodes}
    assert executables == {"node", "managed_node"}
    assert executables <= ros_run_executables()
    assert constant(node_keywords()["package"]) == "physics_mapper"


def test_every_parameter_it_sets_is_one_the_node_declares() -> None:
    declared = {"scene_file", *(spec.name for spec in PARAMETERS), *RCLPY_PARAMETERS}
    assert isinstance(node_keywords()["parameters"], ast.Name)  # the list: a params file and a dict
    tree = ast.parse(LAUNCH.read_text())
    (listed,) = [
        n.value
        for n in ast.walk(tree)
        if isinstance(n, ast.Assign) and [getattr(t, "id", None) for t in n.targets] == ["parameters"]
    ]
    assert isinstance(listed, ast.List)
    dicts = [element for element in listed.elts if isinstance(element, ast.Dict)]
    named = {ast.literal_eval(k) for d in dicts for k in d.keys if k is not None}
    assert named and named <= declared
    assert "use_sim_time" in named


def test_its_default_files_are_shipped() -> None:
    defaults = {ast.literal_eval(call.args[0]): call for call in calls("DeclareLaunchArgument")}
    scene = ast.literal_eval(keyword(defaults["scene_file"], "default_value"))
    assert scene.startswith("package://physics_mapper/")
    assert (REPO / scene.removeprefix("package://physics_mapper/")).is_file()
    params = keyword(defaults["params_file"], "default_value")
    assert isinstance(params, ast.Call) and isinstance(params.args[0], ast.List)  # PathJoinSubstitution([...])
    parts = [ast.literal_eval(e) for e in params.args[0].elts[1:]]  # after FindPackageShare(PACKAGE)
    assert (REPO.joinpath(*parts)).is_file()


def test_every_launch_argument_is_used() -> None:
    declared = {ast.literal_eval(call.args[0]) for call in calls("DeclareLaunchArgument")}
    used = {ast.literal_eval(call.args[0]) for call in calls("LaunchConfiguration")}
    assert declared == used


def test_a_wheel_installs_no_ros2_run_script_and_no_top_level_package(tmp_path: Path) -> None:
    """pip's ``bin/`` would get a ``node`` that shadows Node.js, and a generic top-level package."""
    sources = tmp_path / "src"  # a copy: building in place would leave build/ in the checkout
    shutil.copytree(REPO, sources, ignore=not_sources)
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", str(tmp_path), "."],
        cwd=sources,
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    assert "tests_require" not in built.stdout + built.stderr  # setuptools warns of it on every build
    (wheel,) = tmp_path.glob("*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        entry_points = next(archive.read(n).decode() for n in names if n.endswith("entry_points.txt"))
        modes = {Path(info.filename).name: info.external_attr >> 16 for info in archive.infolist()}
    assert entry_points.split() == ["[console_scripts]", "physics-mapper", "=", "physics_mapper.cli:main"]
    packages = {name.split("/")[0] for name in names if name.endswith(".py") and ".data/" not in name}
    assert packages == {"physics_mapper"}
    # ros2 run's scripts: executable data of lib/physics_mapper (a pip install's <prefix>/lib/physics_mapper/)
    for script in ("node", "managed_node"):
        assert f"physics_mapper-0.1.0.data/data/lib/physics_mapper/{script}" in names
        assert modes[script] & 0o111
    assert not [name for name in names if ".data/scripts/" in name]


def test_the_node_takes_the_log_level_and_the_clock_arguments() -> None:
    declared = {ast.literal_eval(call.args[0]) for call in calls("DeclareLaunchArgument")}
    assert {"use_sim_time", "log_level", "namespace", "autostart", "managed"} <= declared
    arguments = node_keywords()["ros_arguments"]
    assert isinstance(arguments, ast.List) and constant(arguments.elts[0]) == "--log-level"
    (level,) = [e for e in arguments.elts[1:] if isinstance(e, ast.Call)]
    assert ast.literal_eval(level.args[0]) == "log_level"


def transition_of(change: ast.Call) -> str:
    transition = keyword(change, "transition_id")
    assert isinstance(transition, ast.Attribute)
    return transition.attr


def test_autostart_configures_the_managed_node_then_activates_it_once_configured() -> None:
    """nav2's lifecycle manager's order: configure at start, activate when configuring has ended in inactive."""
    changes = calls("ChangeState")
    assert sorted(transition_of(change) for change in changes) == ["TRANSITION_ACTIVATE", "TRANSITION_CONFIGURE"]
    (handler,) = calls("OnStateTransition")
    assert constant(keyword(handler, "start_state")) == "configuring"  # not after a user's deactivate
    assert constant(keyword(handler, "goal_state")) == "inactive"
    (inner,) = [n for n in ast.walk(handler) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "ChangeState"]
    assert transition_of(inner) == "TRANSITION_ACTIVATE"
    # Both only where the node is managed and autostart is true.
    (both,) = calls("AndSubstitution")
    assert [ast.literal_eval(arg.args[0]) for arg in both.args if isinstance(arg, ast.Call)] == ["autostart"]
    configure = [e for e in calls("EmitEvent") if any(k.arg == "condition" for k in e.keywords)]
    for action in calls("RegisterEventHandler") + configure:
        condition = keyword(action, "condition")
        assert isinstance(condition, ast.Call) and ast.unparse(condition) == "IfCondition(autostart)"
