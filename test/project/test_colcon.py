"""The ament_python layout: ``colcon build`` installs what ``ros2 run physics_mapper node`` needs, and it runs."""

from __future__ import annotations

import json
import re
import signal
import subprocess
from pathlib import Path

import pytest
from conftest import COLCON, PACKAGE, REPO, run_installed
from ros_helpers import RosClient, object_status, search_status

#: Runs the installed ``node`` script's own code (argv[1]) without starting the node, loads its
#: entry point as the script does, and prints where the entry point and our packages came from.
IMPORT_PROBE = """
import json, os, runpy, sys
script = sys.argv[1]
sys.path[0] = os.path.dirname(script)  # as when the script itself runs
entry = runpy.run_path(script)
main = entry["load_entry_point"](entry["__requires__"], "console_scripts", "node")
import physics_mapper, physics_mapper.msg_adapters
files = {"entry point": sys.modules[main.__module__].__file__}
files.update({m.__name__: m.__file__ for m in (physics_mapper, physics_mapper.msg_adapters)})
print(json.dumps(files))
"""


@pytest.fixture(scope="module")
def workspace(colcon_workspace: Path) -> Path:
    return colcon_workspace


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
    scene = f"package://{PACKAGE}/config/scenes/pyramid.yaml"  # found through the ament index
    command = (
        f"source install/setup.bash && exec install/{PACKAGE}/lib/{PACKAGE}/node "
        f"--ros-args -p scene_file:={scene} -r __ns:=/colcon"
    )
    log_path = tmp_path / "node.log"
    with log_path.open("w") as log:
        process = subprocess.Popen(["bash", "-c", command], cwd=workspace, stdout=log, stderr=subprocess.STDOUT)
        client = RosClient("/colcon")
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
    assert object_status(diagnostics, "cube_top").message == "no PoseArray received yet"
    installed_scene = workspace / "install" / PACKAGE / "share" / PACKAGE / "config" / "scenes" / "pyramid.yaml"
    assert f"scene {installed_scene}:" in output
    assert code == 0, output


def test_the_installed_node_imports_the_installed_packages(workspace: Path) -> None:
    """The venv's editable install could stand in for a broken install: the node must not need it."""
    script = workspace / "install" / PACKAGE / "lib" / PACKAGE / "node"
    interpreter = script.read_text().splitlines()[0].removeprefix("#!")
    command = 'source install/setup.bash && exec "$0" -c "$1" "$2"'
    probe = subprocess.run(
        ["bash", "-c", command, interpreter, IMPORT_PROBE, str(script)],
        cwd=workspace,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
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
