"""``physics-mapper demo`` (what ``make demo`` runs) and the input errors of ``demo`` and ``publish``."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import REPO
from ros_helpers import run_cli

from physics_mapper.scene import load_problem


def test_demo_starts_the_node_feeds_it_and_prints_the_map() -> None:
    completed = run_cli("demo", cwd=REPO, timeout=120)
    assert completed.returncode == 0, completed.stdout + completed.stderr
    out = completed.stdout
    names = load_problem(REPO / "config" / "problems" / "pyramid.yaml").scene.object_names
    lines = out.splitlines()
    start = lines.index("configuration on ~/configuration (frame 'world'):")
    assert [line.split()[0] for line in lines[start + 1 : start + 1 + len(names)]] == list(names)
    assert any(line.startswith("diagnostics: valid C") for line in lines)
    assert "  nodes visited: " in out and "  rejected by collision: " in out
    assert lines[-1] == "node stopped (exit code 0)"


def test_demo_refuses_a_problem_for_another_scene(tmp_path: Path) -> None:
    completed = run_cli("demo", "--scene", str(REPO / "config" / "scenes" / "stack.yaml"), cwd=REPO)
    assert completed.returncode == 2
    assert completed.stderr.strip().startswith("physics-mapper demo: error: config/problems/pyramid.yaml has objects")
    assert len(completed.stderr.strip().splitlines()) == 1


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
