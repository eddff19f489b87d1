"""The ament_python layout: ``colcon build`` installs what ``ros2 run physics_mapper node`` needs, and it runs."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import COLCON, PACKAGE, REPO, not_sources, run_installed
from ros_helpers import RosClient, object_status, search_status

#: Runs the installed ``node`` script's own code (argv[1]) without starting the node (it starts it
#: only as ``__main__``), and prints where its ``main`` and our packages came from.
IMPORT_PROBE = """
import json, os, runpy, sys
script = sys.argv[1]
sys.path[0] = os.path.dirname(script)  # as when the script itself runs
main = runpy.run_path(script)["main"]
import physics_mapper, physics_mapper.msg_adapters
files = {"entry point": sys.modules[main.__module__].__file__}
files.update({m.__name__: m.__file__ for m in (physics_mapper, physics_mapper.msg_adapters)})
print(json.dumps(files))
"""


def ros_environment() -> dict[str, str]:
    """This run's environment (its ROS domain) with this venv's ``python3`` first on PATH: ``ros2 run``'s
    scripts start with ``#!/usr/bin/env python3``, the ``python3`` of the sourced ROS environment."""
    return {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}


@pytest.fixture(scope="module")
def workspace(colcon_workspace: Path) -> Path:
    return colcon_workspace


@pytest.fixture(scope="module")
def symlink_workspace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A workspace built with ``colcon build --symlink-install`` (setuptools 80: colcon-core#696)."""
    root = tmp_path_factory.mktemp("colcon_symlink_ws")
    shutil.copytree(REPO, root / "src" / PACKAGE, ignore=not_sources)
    built = subprocess.run(
        [str(COLCON), "build", "--symlink-install"], cwd=root, capture_output=True, text=True, timeout=300, check=False
    )
    assert built.returncode == 0, built.stdout + built.stderr
    return root


def test_colcon_lists_an_ament_python_package(workspace: Path) -> None:
    listed = subprocess.run([str(COLCON), "list"], cwd=workspace, capture_output=True, text=True, check=True).stdout
    assert listed.split() == [PACKAGE, f"src/{PACKAGE}", "(ros.ament_python)"]


def test_colcon_build_installs_the_ros2_run_layout(workspace: Path) -> None:
    install = workspace / "install" / PACKAGE
    assert (install / "lib" / PACKAGE / "node").is_file()
    assert (install / "lib" / PACKAGE / "managed_node").is_file()
    # The command line is ros2 run's too, not on PATH: the docs say so, and say how to run it.
    assert (install / "lib" / PACKAGE / "physics-mapper").is_file() and not (install / "bin").exists()
    assert "`ros2 run physics_mapper physics-mapper demo`" in (REPO / "docs" / "node.md").read_text()
    assert (install / "share" / PACKAGE / "launch" / "physics_mapper.launch.py").is_file()
    assert (install / "share" / "ament_index" / "resource_index" / "packages" / PACKAGE).is_file()
    assert (install / "share" / PACKAGE / "package.xml").read_text() == (REPO / "package.xml").read_text()
    assert (install / "share" / PACKAGE / "config" / "scenes" / "pyramid.yaml").is_file()
    assert (install / "share" / PACKAGE / "config" / "params" / "node.yaml").is_file()


def test_the_installed_node_runs_with_the_colcon_environment(workspace: Path, tmp_path: Path) -> None:
    run_the_installed_node(workspace, tmp_path, "/colcon")


def run_the_installed_node(workspace: Path, tmp_path: Path, namespace: str) -> None:
    """``ros2 run physics_mapper node`` in ``workspace``: it answers on /diagnostics, with the installed scene."""
    scene = f"package://{PACKAGE}/config/scenes/pyramid.yaml"  # found through the ament index
    command = (
        f"source install/setup.bash && exec install/{PACKAGE}/lib/{PACKAGE}/node "
        f"--ros-args -p scene_file:={scene} -r __ns:={namespace}"
    )
    log_path = tmp_path / "node.log"
    with log_path.open("w") as log:
        process = subprocess.Popen(
            ["bash", "-c", command], cwd=workspace, stdout=log, stderr=subprocess.STDOUT, env=ros_environment()
        )
        client = RosClient(namespace)
        try:
            diagnostics = client.next_diagnostics(lambda d: True, timeout=30.0, what="the installed node's diagnostics")
        finally:
            client.close()
            process.send_signal(signal.SIGINT)
            code = process.wait(timeout=10)
    output = log_path.read_text()
    search = search_status(diagnostics)
    assert search is not None
    assert search.message == "waiting for hypotheses of: cube_left, cube_right, cube_top"
    assert object_status(diagnostics, "cube_top").message == "no hypotheses received yet"
    installed_scene = workspace / "install" / PACKAGE / "share" / PACKAGE / "config" / "scenes" / "pyramid.yaml"
    assert f"scene {installed_scene}:" in output
    assert code == 0, output


def test_the_installed_node_imports_the_installed_packages(workspace: Path) -> None:
    """The venv's editable install could stand in for a broken install: the node must not need it."""
    script = workspace / "install" / PACKAGE / "lib" / PACKAGE / "node"
    assert script.read_text().splitlines()[0] == "#!/usr/bin/env python3"
    command = 'source install/setup.bash && exec python3 -c "$0" "$1"'
    probe = subprocess.run(
        ["bash", "-c", command, IMPORT_PROBE, str(script)],
        cwd=workspace,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        env=ros_environment(),
    )
    assert probe.returncode == 0, probe.stderr
    files = json.loads(probe.stdout.splitlines()[-1])
    (site_packages,) = (workspace.resolve() / "install" / PACKAGE / "lib").glob("python3*/site-packages")
    assert files == {
        "entry point": str(site_packages / PACKAGE / "commands" / "node.py"),
        PACKAGE: str(site_packages / PACKAGE / "__init__.py"),
        f"{PACKAGE}.msg_adapters": str(site_packages / PACKAGE / "msg_adapters" / "__init__.py"),
    }
    assert not (site_packages / "msg_adapters").exists()  # nothing of a generic name at the top level


def test_installed_shipped_files_mirror_the_checkout(workspace: Path) -> None:
    share = workspace / "install" / PACKAGE / "share" / PACKAGE
    for folder in ("config", "test/data"):
        shipped = sorted(p.relative_to(REPO) for p in (REPO / folder).rglob("*") if p.is_file())
        installed = sorted(p.relative_to(share) for p in (share / folder).rglob("*") if p.is_file())
        assert installed == shipped


def test_installed_commands_find_their_files_from_another_directory(workspace: Path, tmp_path: Path) -> None:
    """bench's default problem and experiment's scenes come from the share directory, not the working directory."""
    share = workspace.resolve() / "install" / PACKAGE / "share" / PACKAGE
    bench = run_installed(workspace, "bench physics_costs --repeats 1", cwd=tmp_path)
    assert bench.returncode == 0, bench.stderr
    assert bench.stdout.startswith(f"{share}/config/problems/pyramid.yaml: 3 objects")
    experiment = run_installed(workspace, "experiment peg -o out --runs 1", cwd=tmp_path)
    assert experiment.returncode == 0, experiment.stderr
    assert re.search(r"peg: wrote out/peg\.png", experiment.stderr)
    assert (tmp_path / "out" / "peg.json").is_file()


def test_a_symlink_install_uses_the_sources_in_place(symlink_workspace: Path) -> None:
    """Python files, data files and ros2 run's scripts are links into the sources (the build folder's links)."""
    build = symlink_workspace / "build" / PACKAGE
    sources = symlink_workspace / "src" / PACKAGE
    assert (build / PACKAGE).resolve() == (sources / PACKAGE).resolve()
    install = symlink_workspace / "install" / PACKAGE
    linked = {
        "lib/physics_mapper/node": "scripts/node",
        "lib/physics_mapper/managed_node": "scripts/managed_node",
        "share/physics_mapper/package.xml": "package.xml",
        "share/physics_mapper/config/scenes/pyramid.yaml": "config/scenes/pyramid.yaml",
    }
    for installed, source in linked.items():
        assert (install / installed).is_symlink()
        assert (install / installed).resolve() == (sources / source).resolve()
    assert (install / "lib" / PACKAGE / "physics-mapper").is_file()  # the console script, written by setuptools


def test_the_symlink_installed_node_and_command_line_run(symlink_workspace: Path, tmp_path: Path) -> None:
    run_the_installed_node(symlink_workspace, tmp_path, "/colcon_symlink")
    solved = run_installed(symlink_workspace, f"solve {REPO / 'config' / 'problems' / 'pyramid.yaml'}", cwd=tmp_path)
    assert solved.returncode == 0, solved.stderr
    assert "valid" in solved.stdout


def test_a_plain_build_after_a_symlink_build_replaces_its_links(symlink_workspace: Path, tmp_path: Path) -> None:
    """colcon undoes the symlink install (``setup.py develop --uninstall``) before installing copies."""
    built = subprocess.run([str(COLCON), "build"], cwd=symlink_workspace, capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stdout + built.stderr
    node = symlink_workspace / "install" / PACKAGE / "lib" / PACKAGE / "node"
    assert node.is_file() and not node.is_symlink()
    run_the_installed_node(symlink_workspace, tmp_path, "/colcon_replaced")
