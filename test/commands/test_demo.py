"""``physics-mapper demo`` (what ``make demo`` runs) and the input errors of ``demo`` and ``publish``."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import PACKAGE, REPO, run_installed
from ros_helpers import run_cli

from physics_mapper.model.scene_files import load_scene


def test_demo_replays_the_shipped_bag_into_the_node_and_prints_errors_and_the_map(
    colcon_workspace: Path, tmp_path: Path
) -> None:
    """The demo as installed by colcon, from a folder without config/ or test/data/: it finds its own."""
    completed = run_installed(colcon_workspace, "demo --rate 4", cwd=tmp_path, timeout=180)
    assert completed.returncode == 0, completed.stdout + completed.stderr
    out = completed.stdout
    share = colcon_workspace.resolve() / "install" / PACKAGE / "share" / PACKAGE
    assert out.startswith(f"replaying {share}/test/data/pyramid into a node started on {share}/config/scenes/pyramid")
    names = load_scene(REPO / "config" / "scenes" / "pyramid.yaml").object_names
    lines = out.splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("object ") and "C111" in line)
    assert lines[header].split() == ["object", "C111", "chosen", "settled"]
    # The live node's searches are timed, so the errors vary from run to run (BENCHMARKS.md, "Live
    # replay"); that physics lowers the error on this bag is tested offline (test_replay.py).
    rows = {line.split()[0]: [float(v) for v in line.split()[1:]] for line in lines[header + 1 : header + 5]}
    assert list(rows) == [*names, "total"]
    assert all(value >= 0.0 for row in rows.values() for value in row)
    start = lines.index("last map on ~/configuration (frame 'world'):")
    assert [line.split()[0] for line in lines[start + 1 : start + 1 + len(names)]] == list(names)
    assert any(line.startswith("diagnostics: valid C") for line in lines)
    assert "  nodes visited: " in out and "  rejected by collision: " in out
    assert "Traceback" not in completed.stderr


def test_demo_refuses_a_bag_for_another_scene() -> None:
    completed = run_cli("demo", "--scene", str(REPO / "config" / "scenes" / "stack.yaml"), cwd=REPO)
    assert completed.returncode == 2
    errors = [line for line in completed.stderr.splitlines() if line.startswith("physics-mapper")]
    assert len(errors) == 1 and errors[0].startswith("physics-mapper demo: error:")
    assert "Traceback" not in completed.stderr


@pytest.mark.parametrize(
    ("args", "error"),
    [
        (["--rate", "0"], "--rate must be positive"),
        (["--count", "-1"], "--count must not be negative"),
        (["--namespace", "bad name"], "--namespace 'bad name' is not a valid ROS namespace"),
    ],
)
def test_publish_refuses_bad_arguments_with_one_line(args: list[str], error: str) -> None:
    completed = run_cli("publish", str(REPO / "config" / "problems" / "pyramid.yaml"), *args)
    assert completed.returncode == 2
    lines = [line for line in completed.stderr.splitlines() if not line.startswith("pybullet build time")]
    assert len(lines) == 1
    assert lines[0].startswith(f"physics-mapper publish: error: {error}")


def test_publish_refuses_a_missing_problem_file() -> None:
    completed = run_cli("publish", "no/such/problem.yaml")
    assert completed.returncode == 2
    assert (
        completed.stderr.strip()
        == "physics-mapper publish: error: no/such/problem.yaml: cannot read file: No such file or directory"
    )
